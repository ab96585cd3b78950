//! Quality of an extracted mesh against its source, as docs/QUALITY.md ("How we measure")
//! defines it; `sparc3d eval` prints it.
//!
//! Both meshes are put in the frame where the source's bounding box is centred and its longest
//! side is 1, and points are sampled uniformly by area on each. From those:
//!
//! - **Chamfer distance** `cd`: mean of the two directed mean nearest-neighbour distances
//!   (point to point, L2, not squared). `cd × N` reads in voxels.
//! - **Absolute normal consistency** `anc`: 100 × mean `|n·n′|` over the nearest pairs, both
//!   directions, with the face normals of the sampled triangles.
//! - **F1** at 0.002, 0.005 and 0.01: 100 × harmonic mean of precision (output points within the
//!   threshold of a source point) and recall (source points within it of an output point).
//! - **Components kept**: source components (after welding vertices closer than 1e-7 of the
//!   bounding box diagonal) spanning at least 2 voxels whose sample points are at least 90%
//!   within 2 voxels of the output surface.
//! - **Offset**: mean signed distance from output points to the source surface, in voxels,
//!   positive outside (dilation); only for a closed source.
//!
//! Point-to-point distances between two samplings of the same surface are not zero: with `n`
//! points on area `A` a nearest neighbour lies about `½·√(A/n)` away. The report states that
//! floor, and also the point-to-surface Chamfer distance, which has no such floor.
//!
//! Random numbers come from a counter-based hash of the seed and the sample index, and every
//! sum is taken in index order, so the numbers are the same whatever the thread count. The
//! same seed gives the same samples on identical meshes.
#![deny(missing_docs)]

mod geom;
mod sample;
mod tri_bvh;
mod weld;

use geom::{dist2, dot, Vec3};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use sample::{sample_subset, Faces, Samples};
use serde::{Deserialize, Serialize};
use sparcubes::error::{Error, Result};
use sparcubes::TriMesh;
use tri_bvh::TriBvh;

/// Distance thresholds of the F1 scores, in units of the source's longest side.
pub const F1_THRESHOLDS: [f64; 3] = [0.002, 0.005, 0.01];

/// Fraction of a component's points that must lie near the output for it to count as kept.
pub const KEPT_FRACTION: f64 = 0.9;

/// Distance, in voxels, within which a component's points count as near the output.
pub const KEPT_DISTANCE_VOXELS: f64 = 2.0;

/// Smallest extent, in voxels, of a component that is counted.
pub const MIN_COMPONENT_VOXELS: f64 = 2.0;

/// Fewest points sampled on each counted component, however small its area.
pub const MIN_COMPONENT_SAMPLES: usize = 64;

/// Welding tolerance as a fraction of the source's bounding box diagonal.
pub const WELD_TOLERANCE: f64 = 1e-7;

/// How to evaluate. `Copy`, with the defaults of docs/QUALITY.md ("How we measure").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct EvalOptions {
    /// Points sampled on each mesh.
    pub samples: usize,
    /// Seed of the sampling.
    pub seed: u64,
    /// Grid resolution N that voxel units refer to: a voxel is 1/N of the source's longest
    /// side.
    pub resolution: u32,
}

impl Default for EvalOptions {
    fn default() -> Self {
        Self {
            samples: 100_000,
            seed: 0x5ba3_c3d0,
            resolution: 512,
        }
    }
}

impl EvalOptions {
    /// Checks the ranges; the error names the field.
    pub fn validate(&self) -> Result<()> {
        if self.samples == 0 {
            return Err(Error::InvalidParams("samples must be at least 1".into()));
        }
        if self.resolution == 0 {
            return Err(Error::InvalidParams("resolution must be at least 1".into()));
        }
        Ok(())
    }
}

/// F1 score at one distance threshold.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct F1Score {
    /// Distance threshold, in units of the source's longest side.
    pub threshold: f64,
    /// Percentage of output points within the threshold of a source point.
    pub precision: f64,
    /// Percentage of source points within the threshold of an output point.
    pub recall: f64,
    /// 100 × harmonic mean of precision and recall (0 when both are 0).
    pub f1: f64,
}

/// Everything [`evaluate`] measures. Lengths are in units of the source's longest side unless
/// the name says voxels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct QualityReport {
    /// The options used.
    pub options: EvalOptions,
    /// Triangles of the source.
    pub source_faces: usize,
    /// Triangles of the output.
    pub output_faces: usize,
    /// Source surface area.
    pub source_area: f64,
    /// Output surface area.
    pub output_area: f64,
    /// Chamfer distance (point to point).
    pub cd: f64,
    /// `cd × N`, in voxels.
    pub cd_voxels: f64,
    /// Expected `cd` of two independent samplings of the source itself, `½·√(A/n)`: the
    /// sampling floor below which `cd` means nothing.
    pub cd_floor: f64,
    /// Chamfer distance from sample points to the other mesh's surface (no sampling floor).
    pub cd_surface: f64,
    /// Absolute normal consistency, 0–100.
    pub anc: f64,
    /// F1 scores at [`F1_THRESHOLDS`].
    pub f1: Vec<F1Score>,
    /// Connected components of the welded source, of any size.
    pub source_components: usize,
    /// Source components spanning at least 2 voxels, with some area.
    pub components_total: usize,
    /// Of those, the ones at least 90% within 2 voxels of the output.
    pub components_kept: usize,
    /// Whether the welded source is closed (every edge shared by exactly two triangles).
    pub source_closed: bool,
    /// Whether the output is closed (every edge shared by exactly two triangles) after welding
    /// only bit-identical positions — an extracted mesh has vertices closer than the source's
    /// welding tolerance that are distinct: a watertightness check independent of the
    /// converter's own.
    pub output_closed: bool,
    /// Mean signed distance from output points to the source, in voxels, positive outside;
    /// `None` when the source is not closed.
    pub offset_voxels: Option<f64>,
    /// Mean unsigned distance from output points to the source surface, in voxels.
    pub output_to_source_voxels: f64,
}

/// A mesh in the evaluation frame.
struct Framed {
    positions: Vec<Vec3>,
    faces: Faces,
}

/// Measures `output` against `source` (both in the same frame). Fails when either mesh has no
/// area, an index is out of range, or the options are out of range.
pub fn evaluate(
    source: &TriMesh,
    output: &TriMesh,
    options: &EvalOptions,
) -> Result<QualityReport> {
    options.validate()?;
    let (center, inv, diag) = frame_of(source)?;
    let src = to_frame(source, center, inv, "source")?;
    let welded = weld::weld(&src.positions, WELD_TOLERANCE * diag);
    let closed = weld::is_closed(&source.triangles, &welded);
    let out = to_frame(output, center, inv, "output")?;
    let all_src: Vec<u32> = (0..src.faces.len() as u32).collect();
    let all_out: Vec<u32> = (0..out.faces.len() as u32).collect();
    let (n, seed) = (options.samples, options.seed);
    let src_samples = sample_subset(&src.faces, &all_src, n, seed, 0);
    let out_samples = sample_subset(&out.faces, &all_out, n, seed, 0);
    if src_samples.points.is_empty() || out_samples.points.is_empty() {
        let which = if src_samples.points.is_empty() {
            "source"
        } else {
            "output"
        };
        return Err(Error::EmptyMesh {
            context: which.into(),
            reason: "the surface has zero area".into(),
        });
    }
    let voxels = options.resolution as f64;
    let to_out = nearest_pairs(&src_samples, &out_samples);
    let to_src = nearest_pairs(&out_samples, &src_samples);
    let cd = 0.5 * (mean(to_out.iter().map(|p| p.0)) + mean(to_src.iter().map(|p| p.0)));
    let anc = 50.0 * (mean(to_out.iter().map(|p| p.1)) + mean(to_src.iter().map(|p| p.1)));
    let f1 = F1_THRESHOLDS
        .iter()
        .map(|&t| f1_score(t, &to_src, &to_out))
        .collect();
    // One triangle hierarchy at a time: each is dropped before the other is built.
    let (out_to_surface, topo) = {
        let out_bvh = TriBvh::new(&out.faces);
        let distances = surface_distances(&out_bvh, &src_samples.points);
        (
            distances,
            source_topology(source, &src, &welded, options, &out_bvh),
        )
    };
    let (src_to_surface, signs) = signed_surface_distances(
        source,
        &src,
        &TriBvh::new(&src.faces),
        &out_samples,
        closed.then_some(&welded[..]),
    );
    let cd_surface =
        0.5 * (mean(out_to_surface.iter().copied()) + mean(src_to_surface.iter().copied()));
    let source_area = src.faces.subset_area(&all_src);
    Ok(QualityReport {
        options: *options,
        source_faces: source.triangles.len(),
        output_faces: output.triangles.len(),
        source_area,
        output_area: out.faces.subset_area(&all_out),
        cd,
        cd_voxels: cd * voxels,
        cd_floor: 0.5 * (source_area / n as f64).sqrt(),
        cd_surface,
        anc,
        f1,
        source_components: topo.components,
        components_total: topo.counted,
        components_kept: topo.kept,
        source_closed: closed,
        output_closed: weld::is_closed(&output.triangles, &weld::weld(&out.positions, 0.0)),
        offset_voxels: signs
            .map(|s| voxels * mean(src_to_surface.iter().zip(&s).map(|(d, s)| d * s))),
        output_to_source_voxels: voxels * mean(src_to_surface.iter().copied()),
    })
}

/// Centre of the source's bounding box, 1 / its longest side, and its diagonal in the
/// evaluation frame.
fn frame_of(source: &TriMesh) -> Result<(Vec3, f64, f64)> {
    let (lo, hi) = source.bounds().ok_or_else(|| Error::EmptyMesh {
        context: "source".into(),
        reason: "no triangle".into(),
    })?;
    let longest = (0..3).map(|a| hi[a] - lo[a]).fold(0.0f64, f64::max);
    if !(longest > 0.0 && longest.is_finite()) {
        return Err(Error::EmptyMesh {
            context: "source".into(),
            reason: format!("degenerate bounding box (longest side {longest})"),
        });
    }
    let center = [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]));
    let diag = (0..3)
        .map(|a| ((hi[a] - lo[a]) / longest).powi(2))
        .sum::<f64>()
        .sqrt();
    Ok((center, 1.0 / longest, diag))
}

/// `mesh` moved by `−center` and scaled by `inv`, as flat triangles.
fn to_frame(mesh: &TriMesh, center: Vec3, inv: f64, what: &str) -> Result<Framed> {
    let positions: Vec<Vec3> = mesh
        .positions
        .iter()
        .map(|p| [0, 1, 2].map(|a| (p[a] as f64 - center[a]) * inv))
        .collect();
    let corners = mesh
        .triangles
        .iter()
        .map(|t| {
            let corner = |i: u32| {
                positions
                    .get(i as usize)
                    .copied()
                    .ok_or_else(|| Error::EmptyMesh {
                        context: what.into(),
                        reason: format!(
                            "vertex index {i} out of range ({} vertices)",
                            positions.len()
                        ),
                    })
            };
            Ok([corner(t[0])?, corner(t[1])?, corner(t[2])?])
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(Framed {
        positions,
        faces: Faces::new(corners),
    })
}

/// For every point of `from`, the distance to its nearest point of `to` and `|n·n′|`.
///
/// Exact nearest neighbours from a kd-tree (`kiddo`'s immutable tree, which copes with many
/// points sharing a coordinate, as samples on a flat face do). The distance is recomputed from
/// the point found, so it does not depend on how the tree sums its squares.
fn nearest_pairs(from: &Samples, to: &Samples) -> Vec<(f64, f64)> {
    if to.points.is_empty() {
        return vec![(f64::INFINITY, 0.0); from.points.len()];
    }
    let tree: ImmutableKdTree<f64, 3> = ImmutableKdTree::new_from_slice(&to.points);
    from.points
        .par_iter()
        .zip(&from.normals)
        .map(|(&p, &n)| {
            let j = tree.nearest_one::<SquaredEuclidean>(&p).item as usize;
            (dist2(p, to.points[j]).sqrt(), dot(n, to.normals[j]).abs())
        })
        .collect()
}

/// F1 at threshold `t` from output→source (`precision`) and source→output (`recall`) pairs.
fn f1_score(t: f64, to_src: &[(f64, f64)], to_out: &[(f64, f64)]) -> F1Score {
    let within = |pairs: &[(f64, f64)]| {
        100.0 * pairs.iter().filter(|p| p.0 < t).count() as f64 / pairs.len().max(1) as f64
    };
    let (precision, recall) = (within(to_src), within(to_out));
    let f1 = if precision + recall > 0.0 {
        2.0 * precision * recall / (precision + recall)
    } else {
        0.0
    };
    F1Score {
        threshold: t,
        precision,
        recall,
        f1,
    }
}

/// Distance from every point to the surface under `bvh`.
fn surface_distances(bvh: &TriBvh, points: &[Vec3]) -> Vec<f64> {
    points
        .par_iter()
        .map(|&p| bvh.closest(p).map_or(f64::INFINITY, |c| c.dist2.sqrt()))
        .collect()
}

/// Distance from every output sample to the source surface, and its sign (+1 outside) when
/// the source is closed (`closed_welded` holds its welded vertex ids then).
fn signed_surface_distances(
    source: &TriMesh,
    src: &Framed,
    bvh: &TriBvh,
    out_samples: &Samples,
    closed_welded: Option<&[u32]>,
) -> (Vec<f64>, Option<Vec<f64>>) {
    let Some(welded) = closed_welded else {
        return (surface_distances(bvh, &out_samples.points), None);
    };
    let oracle = weld::SignOracle::new(&src.faces, &source.triangles, welded);
    let (dist, sign) = out_samples
        .points
        .par_iter()
        .map(|&p| match bvh.closest(p) {
            Some(c) => (c.dist2.sqrt(), oracle.sign(p, &c, &src.faces)),
            None => (f64::INFINITY, 1.0),
        })
        .unzip();
    (dist, Some(sign))
}

/// Component counts of the source.
struct Topology {
    /// All components.
    components: usize,
    /// Components spanning at least [`MIN_COMPONENT_VOXELS`], with some area.
    counted: usize,
    /// Counted components the output keeps.
    kept: usize,
}

/// Splits the welded source into components and checks which ones the output keeps.
fn source_topology(
    source: &TriMesh,
    src: &Framed,
    welded: &[u32],
    options: &EvalOptions,
    out_bvh: &TriBvh,
) -> Topology {
    let (labels, count) = weld::components(&source.triangles, welded);
    let groups = group_by_label(&labels, count);
    let voxel = 1.0 / options.resolution as f64;
    let total_area = src.faces.areas.iter().sum::<f64>();
    let verdicts: Vec<Option<bool>> = groups
        .par_iter()
        .enumerate()
        .map(|(c, tris)| {
            let area = src.faces.subset_area(tris);
            if extent(&src.faces, tris) < MIN_COMPONENT_VOXELS * voxel || area <= 0.0 {
                return None;
            }
            let share = (options.samples as f64 * area / total_area).ceil() as usize;
            let count = share.max(MIN_COMPONENT_SAMPLES);
            let s = sample_subset(&src.faces, tris, count, options.seed, 1 + c as u64);
            let limit2 = (KEPT_DISTANCE_VOXELS * voxel).powi(2);
            let near = s
                .points
                .iter()
                .filter(|&&p| out_bvh.closest(p).is_some_and(|h| h.dist2 <= limit2))
                .count();
            Some(near as f64 >= KEPT_FRACTION * s.points.len() as f64)
        })
        .collect();
    Topology {
        components: count,
        counted: verdicts.iter().flatten().count(),
        kept: verdicts.iter().flatten().filter(|&&k| k).count(),
    }
}

/// Triangle indices grouped by component label (labels in `0..count`).
fn group_by_label(labels: &[u32], count: usize) -> Vec<Vec<u32>> {
    let mut groups = vec![Vec::new(); count];
    for (t, &l) in labels.iter().enumerate() {
        groups[l as usize].push(t as u32);
    }
    groups
}

/// Longest side of the bounding box of the listed triangles.
fn extent(faces: &Faces, tris: &[u32]) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for &t in tris {
        for p in &faces.corners[t as usize] {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
    }
    (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max)
}

/// Mean of the values, summed in order (0 for none).
fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sparcubes::shapes;

    /// Seeded samples on a mesh of `shapes`, in `f64`.
    fn samples_on(mesh: &TriMesh, n: usize, seed: u64) -> Samples {
        let Ok(framed) = to_frame(mesh, [0.0; 3], 1.0, "test") else {
            panic!("a generated mesh has only valid indices");
        };
        let all: Vec<u32> = (0..framed.faces.len() as u32).collect();
        sample_subset(&framed.faces, &all, n, seed, 0)
    }

    #[test]
    fn nearest_pairs_are_the_exact_nearest_points() {
        // Many samples on flat faces share a coordinate: the case a kd-tree must get right.
        let cube = shapes::cuboid([0.0; 3], [1.0; 3], &[]);
        let torus = shapes::torus([0.5, 0.5, 0.5], 0.4, 0.1, 16);
        let (from, to) = (samples_on(&torus, 3000, 1), samples_on(&cube, 2000, 2));
        let pairs = nearest_pairs(&from, &to);
        assert_eq!(pairs.len(), from.points.len());
        for ((p, n), &(d, c)) in from.points.iter().zip(&from.normals).zip(&pairs) {
            let best = (0..to.points.len())
                .min_by(|&i, &j| dist2(*p, to.points[i]).total_cmp(&dist2(*p, to.points[j])));
            let Some(j) = best else {
                panic!("no sample on the cube");
            };
            assert_eq!(d, dist2(*p, to.points[j]).sqrt(), "point {p:?}");
            assert_eq!(c, dot(*n, to.normals[j]).abs(), "point {p:?}");
        }
    }

    #[test]
    fn nothing_to_pair_with_is_infinitely_far() {
        let from = samples_on(&shapes::cuboid([0.0; 3], [1.0; 3], &[]), 10, 1);
        let to = Samples::default();
        assert!(nearest_pairs(&from, &to)
            .iter()
            .all(|&(d, c)| d == f64::INFINITY && c == 0.0));
    }
}
