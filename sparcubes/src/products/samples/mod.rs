//! Point samples for vector-set VAEs (as 3DShape2VecSet introduced them; the consumers, their
//! rules and their files are `sparc3d-formats`' and docs/FORMAT.md's), drawn from the
//! watertight output mesh of one item:
//!
//! - **surface**: points uniform by area, with the unit normal of their triangle;
//! - **sharp**: points uniform by length on the edges whose dihedral angle is at least
//!   `sharp_angle_deg`, with the normalised mean of the two face normals (the consumers' edge
//!   normal);
//! - **near**: area-uniform surface points moved by a truncated normal offset per axis
//!   (σ cycling through `near_sigmas`), with their signed distance;
//! - **sharp_near**: points on the sharp edges, drawn as the sharp ones, moved the same way
//!   (σ cycling through `sharp_near_sigmas`), with their signed distance;
//! - **volume**: points uniform in `[-volume_bound, volume_bound]³`, with their signed
//!   distance and occupancy.
//!
//! Everything is in the job's **normalized frame**: the grid cube `[0, N]³` mapped onto
//! `[-1, 1]³` (`p = 2·g/N − 1`, so `p = 2·(source − center)·scale`). Distances are exact
//! distances to the extracted mesh ([`crate::queries::closest`]); their sign, negative inside, comes
//! from the closest triangle's face where the closest point lies strictly inside it
//! ([`TriangleIndex::face_side`], exact for the closed output mesh of the sparse grid), else
//! from the sparse grid ([`crate::queries::sides`]). Before the grid sides set aside crossings that
//! graze a triangle's border, the two differed on about one near point in 2000
//! (storage-rounded points on the grid's dyadic planes, where the grid's crossing count met a
//! triangle edge), and there the face was right by the winding number
//! (docs/record/PERFORMANCE-history.md, issue 13 section); now they agree (tests). Query
//! points are rounded to the storage precision first, so a stored point and its stored
//! distance belong together; a distance too small for the precision keeps its sign as the
//! smallest subnormal.
//!
//! Every random number is drawn from `(seed, kind, sample index)` ([`rng`]), so the samples
//! are the same whatever the thread count. [`farthest_points`] picks a farthest-point
//! subset of drawn points, for a consumer whose files hold one.

mod fps;
pub mod rng;
mod sharp;
mod surface;

use crate::error::{Error, Result};
use crate::grid::cubes::SparseCubes;
use crate::mesh::TriMesh;
use crate::queries::closest::TriangleIndex;
use crate::queries::sides::GridSides;
pub use fps::farthest_points;
use rayon::prelude::*;
use rng::Draw;
use serde::{Deserialize, Serialize};
pub use sharp::sharp_edges;
use sharp::SharpEdges;
use surface::AreaTable;

/// Most samples of one kind per item (16 Mi): 16 Mi points of `f32` are 192 MiB.
pub const MAX_PER_KIND: usize = 1 << 24;

/// Storage precision of sample coordinates, normals and distances.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// IEEE half precision (`<f2`).
    F16,
    /// IEEE single precision (`<f4`).
    F32,
}

impl Precision {
    /// `x` rounded to this precision (round to nearest even).
    #[inline]
    pub fn round(self, x: f64) -> f64 {
        match self {
            Precision::F16 => half::f16::from_f64(x).to_f64(),
            Precision::F32 => x as f32 as f64,
        }
    }

    /// A signed distance rounded to this precision, keeping its side: a magnitude that rounds
    /// to zero becomes the smallest positive subnormal with the distance's sign.
    #[inline]
    pub fn round_signed(self, magnitude: f64, inside: bool) -> f64 {
        let mut r = self.round(magnitude);
        if r == 0.0 {
            r = match self {
                Precision::F16 => half::f16::from_bits(1).to_f64(),
                Precision::F32 => f32::from_bits(1) as f64,
            };
        }
        if inside {
            -r
        } else {
            r
        }
    }
}

/// How many samples of each kind, and how they are drawn. The defaults ([`SampleParams::default`])
/// draw enough of every kind for every vector-set consumer of `sparc3d-formats` at once.
///
/// `sharp_near` and `sharp_near_sigmas` are read as 0 and empty when a stored config lacks
/// them and are left out of the config's JSON while so (as `Params::seal_openings`): a job
/// stored before the kind existed keeps its fingerprint and resumes drawing what it drew.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SampleParams {
    /// Area-uniform surface points.
    pub surface: usize,
    /// Points on sharp edges.
    pub sharp: usize,
    /// Points near the surface, with signed distance.
    pub near: usize,
    /// Points near sharp edges, with signed distance.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub sharp_near: usize,
    /// Points uniform in the volume, with signed distance and occupancy.
    pub volume: usize,
    /// Standard deviations of the near points' offsets (normalized units), used in turn: row
    /// `i` uses `near_sigmas[i mod len]` ([`sigma_rows`]).
    pub near_sigmas: Vec<f64>,
    /// Standard deviations of the sharp-near points' offsets, used in turn as `near_sigmas`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sharp_near_sigmas: Vec<f64>,
    /// Largest offset per axis of a near or sharp-near point (normalized units).
    pub near_bound: f64,
    /// Half the side of the volume sampling cube (normalized units).
    pub volume_bound: f64,
    /// Smallest dihedral angle of a sharp edge, in degrees.
    pub sharp_angle_deg: f64,
    /// Storage precision (`"f16"` or `"f32"`).
    pub dtype: Precision,
    /// Seed of every random number.
    pub seed: u64,
}

/// Whether a count is 0 (serde's `skip_serializing_if` for [`SampleParams::sharp_near`]).
fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl Default for SampleParams {
    /// One draw that serves every consumer by its own rule; an exporter takes each one's
    /// rows (a prefix, or the rows of one σ by [`sigma_rows`]). Each count, σ, bound, the
    /// sharp-edge angle and the `f16` storage is what one of the vector-set consumers draws
    /// or stores, or the union of several: docs/FORMAT.md, "Samples for vector-set VAEs",
    /// names them with the file and line of each consumer's own source.
    fn default() -> Self {
        Self {
            surface: 204_800,
            sharp: 124_928,
            near: 600_000,
            sharp_near: 262_144,
            volume: 249_856,
            near_sigmas: vec![0.001, 0.005, 0.05],
            sharp_near_sigmas: vec![0.001, 0.003, 0.005, 0.007, 0.01, 0.02, 0.04, 0.06],
            near_bound: 0.25,
            volume_bound: 1.05,
            sharp_angle_deg: 15.0,
            dtype: Precision::F16,
            seed: 0,
        }
    }
}

/// The σ of row `i` of a kind whose offsets cycle through `sigmas` (not empty).
fn sigma_of(sigmas: &[f64], i: u64) -> f64 {
    sigmas[(i % sigmas.len() as u64) as usize]
}

/// The rows, in order, of a kind of `count` rows drawn with σ = `sigma` when the σ cycle
/// through `sigmas` (row `i` uses `sigmas[i mod len]`, as `near` with `near_sigmas` and
/// `sharp_near` with `sharp_near_sigmas`). `sigma` is compared exactly, as written in the
/// config; none when it is not in `sigmas`. The first 200000 near rows at σ 0.001:
/// `sigma_rows(p.near, &p.near_sigmas, 0.001).take(200_000)`.
pub fn sigma_rows(count: usize, sigmas: &[f64], sigma: f64) -> impl Iterator<Item = usize> {
    let len = sigmas.len().max(1);
    let hits: Vec<usize> = (0..sigmas.len()).filter(|&j| sigmas[j] == sigma).collect();
    let count = if hits.is_empty() { 0 } else { count };
    (0..count).filter(move |i| hits.contains(&(i % len)))
}

impl SampleParams {
    /// The params with `sharp_near_sigmas` emptied when no sharp-near point is drawn, so a
    /// config that sets `sharp_near = 0` is the config of a job from before the kind existed
    /// (the σ of no point do not decide anything).
    pub fn settled(self) -> Self {
        Self {
            sharp_near_sigmas: if self.sharp_near == 0 {
                Vec::new()
            } else {
                self.sharp_near_sigmas
            },
            ..self
        }
    }

    /// Checks every field; the error names the key (`samples.<field>`).
    pub fn validate(&self) -> Result<()> {
        self.validate_counts()?;
        check_sigmas("near_sigmas", self.near, &self.near_sigmas)?;
        check_sigmas(
            "sharp_near_sigmas",
            self.sharp_near,
            &self.sharp_near_sigmas,
        )?;
        for (key, value) in [
            ("near_bound", self.near_bound),
            ("volume_bound", self.volume_bound),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return invalid(key, format!("{value} is not a positive number"));
            }
        }
        if !(0.0..=180.0).contains(&self.sharp_angle_deg) {
            return invalid(
                "sharp_angle_deg",
                format!("{} is not in [0, 180]", self.sharp_angle_deg),
            );
        }
        Ok(())
    }

    /// Every count at most [`MAX_PER_KIND`].
    fn validate_counts(&self) -> Result<()> {
        for (key, n) in [
            ("surface", self.surface),
            ("sharp", self.sharp),
            ("near", self.near),
            ("sharp_near", self.sharp_near),
            ("volume", self.volume),
        ] {
            if n > MAX_PER_KIND {
                return invalid(
                    key,
                    format!(
                        "{n} samples per item would not fit in memory (at most {MAX_PER_KIND})"
                    ),
                );
            }
        }
        Ok(())
    }
}

/// An invalid `samples.<key>`.
fn invalid(key: &str, why: String) -> Result<()> {
    Err(Error::InvalidParams(format!("samples.{key}: {why}")))
}

/// The σ list `key` of a kind drawing `count` points: not empty when `count > 0`, every σ
/// positive.
fn check_sigmas(key: &str, count: usize, sigmas: &[f64]) -> Result<()> {
    let kind = key.trim_end_matches("_sigmas");
    if count > 0 && sigmas.is_empty() {
        return invalid(key, format!("needs at least one value when {kind} > 0"));
    }
    match sigmas.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
        Some(s) => invalid(key, format!("{s} is not a positive number")),
        None => Ok(()),
    }
}

/// The samples of one item, in the normalized frame, rounded to the storage precision.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Samples {
    /// Surface points.
    pub surface_points: Vec<[f32; 3]>,
    /// Unit normal of each surface point's triangle.
    pub surface_normals: Vec<[f32; 3]>,
    /// Points on sharp edges (empty when the mesh has no sharp edge).
    pub sharp_points: Vec<[f32; 3]>,
    /// Edge normal of each sharp point.
    pub sharp_normals: Vec<[f32; 3]>,
    /// Near-surface points.
    pub near_points: Vec<[f32; 3]>,
    /// Signed distance of each near point to the surface (negative inside).
    pub near_sdf: Vec<f32>,
    /// Points near sharp edges (empty when the mesh has no sharp edge).
    pub sharp_near_points: Vec<[f32; 3]>,
    /// Signed distance of each sharp-near point (negative inside).
    pub sharp_near_sdf: Vec<f32>,
    /// Volume points.
    pub volume_points: Vec<[f32; 3]>,
    /// Signed distance of each volume point (negative inside).
    pub volume_sdf: Vec<f32>,
    /// 1 when the volume point is inside, else 0.
    pub volume_occupancy: Vec<u8>,
    /// Sharp edges found on the mesh (not searched, 0, when neither sharp nor sharp-near
    /// samples are asked for).
    pub sharp_edges: u64,
}

/// Stream numbers of the kinds (each kind draws its own numbers).
const SURFACE: u64 = 1;
const SHARP: u64 = 2;
const NEAR: u64 = 3;
const VOLUME: u64 = 4;
const SHARP_NEAR: u64 = 5;

/// The first random number of a near or sharp-near point's offsets (numbers below are the
/// point's draw on the surface or the edges).
const OFFSET_NUMBERS: u64 = 8;

/// The normalized frame of an item at grid resolution `n`, and the storage precision.
#[derive(Debug, Clone, Copy)]
struct Frame {
    /// Grid resolution.
    n: f64,
    /// Storage precision.
    precision: Precision,
}

impl Frame {
    /// Grid coordinates to the normalized frame.
    fn to_norm(self, g: [f64; 3]) -> [f64; 3] {
        g.map(|c| 2.0 * c / self.n - 1.0)
    }

    /// Normalized coordinates to the grid.
    fn to_grid(self, p: [f64; 3]) -> [f64; 3] {
        p.map(|c| (c + 1.0) * 0.5 * self.n)
    }

    /// A point or vector rounded to the storage precision.
    fn round3(self, p: [f64; 3]) -> [f64; 3] {
        p.map(|c| self.precision.round(c))
    }

    /// A point `p` (normalized) moved by `offset`, rounded.
    fn moved(self, p: [f64; 3], offset: [f64; 3]) -> [f64; 3] {
        self.round3(std::array::from_fn(|a| p[a] + offset[a]))
    }
}

/// A rounded point as stored.
fn store(p: [f64; 3]) -> [f32; 3] {
    p.map(|c| c as f32)
}

/// Draws the samples of `params` from `mesh`, the mesh that [`crate::extract()`] made of
/// `cubes` (grid coordinates). Fails on invalid parameters and on an empty mesh when any
/// sample is asked for.
pub fn sample(cubes: &SparseCubes, mesh: &TriMesh, params: &SampleParams) -> Result<Samples> {
    params.validate()?;
    let frame = Frame {
        n: cubes.resolution as f64,
        precision: params.dtype,
    };
    let wanted = params.surface + params.sharp + params.near + params.sharp_near + params.volume;
    if wanted == 0 {
        return Ok(Samples::default());
    }
    let areas = AreaTable::new(mesh);
    if areas.is_empty() {
        return Err(Error::EmptyMesh {
            context: "samples".into(),
            reason: "the extracted mesh has no triangle of positive area".into(),
        });
    }
    let mut out = Samples::default();
    (out.surface_points, out.surface_normals) = draw_surface(&areas, mesh, params, frame);

    let edges = if params.sharp > 0 || params.sharp_near > 0 {
        sharp_edges(mesh, params.sharp_angle_deg)
    } else {
        Default::default()
    };
    out.sharp_edges = edges.len() as u64;
    (out.sharp_points, out.sharp_normals) = draw_sharp(&edges, params, frame);

    // Near, sharp-near and volume points: positions first (rounded), then exact distances
    // and sides.
    let near = draw_near(&areas, mesh, params, frame);
    let sharp_near = draw_sharp_near(&edges, params, frame);
    let volume = draw_volume(params, frame);
    if !(near.is_empty() && sharp_near.is_empty() && volume.is_empty()) {
        let distances = Distances::new(cubes, mesh, frame);
        (out.near_sdf, _) = distances.signed(&near);
        (out.sharp_near_sdf, _) = distances.signed(&sharp_near);
        let (volume_sdf, inside) = distances.signed(&volume);
        out.near_points = near.into_iter().map(store).collect();
        out.sharp_near_points = sharp_near.into_iter().map(store).collect();
        out.volume_points = volume.into_iter().map(store).collect();
        out.volume_sdf = volume_sdf;
        out.volume_occupancy = inside.into_iter().map(u8::from).collect();
    }
    Ok(out)
}

/// Surface points, area-uniform, with their face normals.
fn draw_surface(
    areas: &AreaTable,
    mesh: &TriMesh,
    params: &SampleParams,
    frame: Frame,
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    areas
        .draw_batch(mesh, (params.seed, SURFACE), params.surface, |_, _, s| {
            (
                store(frame.round3(frame.to_norm(s.point))),
                store(frame.round3(s.normal)),
            )
        })
        .into_iter()
        .unzip()
}

/// Points on the sharp edges with their edge normals (none without sharp edges).
fn draw_sharp(
    edges: &SharpEdges,
    params: &SampleParams,
    frame: Frame,
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    if edges.is_empty() {
        return Default::default();
    }
    (0..params.sharp as u64)
        .into_par_iter()
        .map(|i| {
            let (p, normal) = edges.draw(&Draw::new(params.seed, SHARP, i));
            (
                store(frame.round3(frame.to_norm(p))),
                store(frame.round3(normal)),
            )
        })
        .unzip()
}

/// Near points: area-uniform surface points moved by truncated normal offsets, σ cycling
/// through `near_sigmas`; rounded, not yet stored.
fn draw_near(
    areas: &AreaTable,
    mesh: &TriMesh,
    params: &SampleParams,
    frame: Frame,
) -> Vec<[f64; 3]> {
    let sigmas = &params.near_sigmas;
    areas.draw_batch(mesh, (params.seed, NEAR), params.near, |i, d, s| {
        let offset: [f64; 3] =
            d.truncated_normals(OFFSET_NUMBERS, sigma_of(sigmas, i), params.near_bound);
        frame.moved(frame.to_norm(s.point), offset)
    })
}

/// Sharp-near points: points on the sharp edges (drawn as the sharp ones, from their own
/// numbers) moved by truncated normal offsets, σ cycling through `sharp_near_sigmas`;
/// rounded, not yet stored. None without sharp edges.
fn draw_sharp_near(edges: &SharpEdges, params: &SampleParams, frame: Frame) -> Vec<[f64; 3]> {
    if edges.is_empty() {
        return Vec::new();
    }
    let sigmas = &params.sharp_near_sigmas;
    (0..params.sharp_near as u64)
        .into_par_iter()
        .map(|i| {
            let d = Draw::new(params.seed, SHARP_NEAR, i);
            let (p, _) = edges.draw(&d);
            let offset: [f64; 3] =
                d.truncated_normals(OFFSET_NUMBERS, sigma_of(sigmas, i), params.near_bound);
            frame.moved(frame.to_norm(p), offset)
        })
        .collect()
}

/// Volume points, uniform in the cube of half side `volume_bound`; rounded, not yet stored.
fn draw_volume(params: &SampleParams, frame: Frame) -> Vec<[f64; 3]> {
    let b = params.volume_bound;
    (0..params.volume as u64)
        .into_par_iter()
        .map(|i| {
            let d = Draw::new(params.seed, VOLUME, i);
            frame.round3(std::array::from_fn(|a| {
                b * (2.0 * d.uniform(a as u64) - 1.0)
            }))
        })
        .collect()
}

/// Exact signed distances to the output mesh: its closest-point index, and the grid sides,
/// built only when some point's closest triangle does not give its side.
struct Distances<'a> {
    /// The sparse grid the mesh was extracted from.
    cubes: &'a SparseCubes,
    /// Closest points on the mesh.
    index: TriangleIndex,
    /// The grid sides, once needed.
    sides: std::sync::OnceLock<GridSides<'a>>,
    /// The item's frame.
    frame: Frame,
}

impl<'a> Distances<'a> {
    /// The index of `mesh`, extracted from `cubes`.
    fn new(cubes: &'a SparseCubes, mesh: &TriMesh, frame: Frame) -> Self {
        Self {
            cubes,
            index: TriangleIndex::new(mesh),
            sides: std::sync::OnceLock::new(),
            frame,
        }
    }

    /// The stored signed distance (normalized units, rounded, negative inside) and the side
    /// of each point (normalized, rounded).
    fn signed(&self, points: &[[f64; 3]]) -> (Vec<f32>, Vec<bool>) {
        if points.is_empty() {
            return Default::default();
        }
        let frame = self.frame;
        let grid: Vec<[f64; 3]> = points.par_iter().map(|&p| frame.to_grid(p)).collect();
        let closest = self.index.closest_batch(&grid);
        let inside = face_or_grid_sides(&self.index, &grid, &closest, || {
            self.sides.get_or_init(|| GridSides::new(self.cubes))
        });
        let sdf = closest
            .par_iter()
            .zip(&inside)
            .map(|(c, &ins)| {
                frame
                    .precision
                    .round_signed(c.distance * 2.0 / frame.n, ins) as f32
            })
            .collect();
        (sdf, inside)
    }
}

/// Whether each point (grid coordinates) is inside: from its closest triangle where
/// [`TriangleIndex::face_side`] gives it (most near points), else from the grid sides. The face
/// is cheaper than the grid's local parity test (module docs).
fn face_or_grid_sides<'a>(
    index: &TriangleIndex,
    grid: &[[f64; 3]],
    closest: &[crate::queries::closest::ClosestPoint],
    sides: impl FnOnce() -> &'a GridSides<'a>,
) -> Vec<bool> {
    let face: Vec<Option<bool>> = grid
        .par_iter()
        .zip(closest)
        .map(|(&g, c)| index.face_side(g, c))
        .collect();
    let rest: Vec<[f64; 3]> = grid
        .iter()
        .zip(&face)
        .filter(|(_, f)| f.is_none())
        .map(|(&g, _)| g)
        .collect();
    if rest.is_empty() {
        return face.into_iter().map(|f| f == Some(true)).collect();
    }
    let mut rest = sides().inside_batch(&rest).into_iter();
    face.into_iter()
        .map(|f| f.unwrap_or_else(|| rest.next().unwrap_or(false)))
        .collect()
}

#[cfg(test)]
mod tests;
