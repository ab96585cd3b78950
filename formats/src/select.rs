//! Picking a consumer's rows out of one item's samples: the rows of a kind drawn with a given
//! σ (row `i` of near and sharp-near points has σ `sigmas[i mod len]`,
//! [`sparcubes::samples::sigma_rows`]), volume points inside a consumer's cube, and the counts
//! a job's `[samples]` must reach for a consumer (its `missing` list).

use crate::{Error, Placement, Result};
use sparcubes::samples::{sigma_rows, SampleParams, Samples};

/// How many of `count` rows a kind with `sigmas` draws at `sigma`.
pub(crate) fn count_at(count: usize, sigmas: &[f64], sigma: f64) -> usize {
    sigma_rows(count, sigmas, sigma).count()
}

/// The first `take` rows drawn at `sigma`, or an error naming the kind's keys.
fn rows_at(
    count: usize,
    sigmas: &[f64],
    sigma: f64,
    take: usize,
    kind: &str,
) -> Result<Vec<usize>> {
    let rows: Vec<usize> = sigma_rows(count, sigmas, sigma).take(take).collect();
    if rows.len() < take {
        return Err(Error::Missing(format!(
            "{take} {kind} points at σ {sigma} needed, the job drew {} (samples.{kind} and \
             samples.{kind}_sigmas)",
            rows.len()
        )));
    }
    Ok(rows)
}

/// Consecutive blocks of a kind's rows, each `(σ, rows)`: the first rows drawn at that σ.
pub(crate) type Blocks = [(f64, usize)];

/// The rows of `blocks` in turn, or an error naming the kind's keys.
pub(crate) fn block_rows(
    count: usize,
    sigmas: &[f64],
    blocks: &Blocks,
    kind: &str,
) -> Result<Vec<usize>> {
    let mut out = Vec::with_capacity(blocks.iter().map(|b| b.1).sum());
    for &(sigma, take) in blocks {
        out.extend(rows_at(count, sigmas, sigma, take, kind)?);
    }
    Ok(out)
}

/// What `blocks` need of `[samples]` key `key` (drawing `count` rows with `sigmas`).
pub(crate) fn block_needs(
    key: &'static str,
    count: usize,
    sigmas: &[f64],
    blocks: &Blocks,
) -> Vec<Need> {
    blocks
        .iter()
        .map(|&(sigma, want)| Need::at_sigma(key, count, sigmas, sigma, want))
        .collect()
}

/// The rows of the sharp-near `blocks`, or an error naming the kind's keys.
pub(crate) fn sharp_near_rows(
    s: &Samples,
    p: &SampleParams,
    blocks: &Blocks,
) -> Result<Vec<usize>> {
    block_rows(
        s.sharp_near_points.len(),
        &p.sharp_near_sigmas,
        blocks,
        "sharp_near",
    )
}

/// The first `take` rows (fewer when fewer lie there) whose point, moved by `place`, lies in
/// the cube `[−bound, bound]³`.
pub(crate) fn rows_in_cube(
    points: &[[f32; 3]],
    place: &Placement,
    bound: f64,
    take: usize,
) -> Vec<usize> {
    points
        .iter()
        .enumerate()
        .filter(|(_, &p)| place.point(p).iter().all(|c| c.abs() <= bound))
        .map(|(i, _)| i)
        .take(take)
        .collect()
}

/// One requirement a consumer puts on `[samples]`: at least `want` rows of `key` (at σ
/// `sigma` when given), the job draws `have`.
pub(crate) struct Need {
    /// The `[samples]` key.
    pub key: &'static str,
    /// The σ the rows must be drawn at, if any.
    pub sigma: Option<f64>,
    /// Rows the job draws (at that σ).
    pub have: usize,
    /// Rows the consumer needs.
    pub want: usize,
}

impl Need {
    /// A count of `key` rows.
    pub fn rows(key: &'static str, have: usize, want: usize) -> Self {
        Self {
            key,
            sigma: None,
            have,
            want,
        }
    }

    /// A count of `key` rows at `sigma` among `count` rows drawn with `sigmas`.
    pub fn at_sigma(
        key: &'static str,
        count: usize,
        sigmas: &[f64],
        sigma: f64,
        want: usize,
    ) -> Self {
        Self {
            key,
            sigma: Some(sigma),
            have: count_at(count, sigmas, sigma),
            want,
        }
    }
}

/// A consumer's `missing` list: the one line of a job without samples, else the unmet needs
/// `needs` finds in the job's `[samples]`.
pub(crate) fn missing_needs(
    samples: Option<&SampleParams>,
    needs: impl FnOnce(&SampleParams) -> Vec<Need>,
) -> Vec<String> {
    match samples {
        None => samples_off(),
        Some(p) => unmet(&needs(p)),
    }
}

/// What a consumer reading `rows` surface points and `rows` sharp-edge points needs.
pub(crate) fn surface_and_sharp_needs(p: &SampleParams, rows: usize) -> Vec<Need> {
    vec![
        Need::rows("surface", p.surface, rows),
        Need::rows("sharp", p.sharp, rows),
    ]
}

/// What the sharp-near `blocks` need of `[samples]`.
pub(crate) fn sharp_near_needs(p: &SampleParams, blocks: &Blocks) -> Vec<Need> {
    block_needs("sharp_near", p.sharp_near, &p.sharp_near_sigmas, blocks)
}

/// The unmet needs, each as one line naming the key.
fn unmet(needs: &[Need]) -> Vec<String> {
    needs
        .iter()
        .filter(|n| n.have < n.want)
        .map(|n| match n.sigma {
            Some(s) => format!(
                "samples.{}: at least {} rows at σ {s} (samples.{}_sigmas must list {s}); the \
                 job draws {}",
                n.key, n.want, n.key, n.have
            ),
            None => format!(
                "samples.{}: at least {} rows; the job draws {}",
                n.key, n.want, n.have
            ),
        })
        .collect()
}

/// The one line for a job without samples.
fn samples_off() -> Vec<String> {
    vec!["samples.enabled = true (the job draws no samples)".into()]
}

/// Whether the item has at least `want` sharp-edge points (none when the mesh has no edge
/// sharper than `samples.sharp_angle_deg`).
pub(crate) fn has_sharp(s: &Samples, want: usize) -> bool {
    s.sharp_points.len() >= want
}

/// An error unless the item has at least `want` sharp-edge points, for a consumer whose loader
/// reads them and whose own sampler writes nothing for a mesh without a sharp edge (Dora's
/// `sharp_sample.py` L257-258, Hunyuan3D-2.1's `sharp_sample_pointcloud`, which indexes an
/// empty edge list): such an item is left out, as `who`'s own sampler leaves it
/// ([`Error::LeftOut`]); too few points from a mesh that has sharp edges is a job drawing too
/// few ([`Error::Missing`]).
pub(crate) fn require_sharp(s: &Samples, want: usize, who: &str) -> Result<()> {
    match s.sharp_points.len() {
        n if n >= want => Ok(()),
        0 => Err(Error::LeftOut(format!(
            "no sharp edges, as {who}'s own sampler"
        ))),
        n => Err(Error::Missing(format!(
            "{n} sharp-edge points, {who} needs {want} (raise samples.sharp)"
        ))),
    }
}
