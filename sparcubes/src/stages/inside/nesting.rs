//! Solids nested in solids: a region wholly inside another ([`Nesting`]) bounds no material
//! with its surface, which the sign stage then does not keep.

use super::regions::{Regions, NO_REGION};
use super::vote::Verdict;
use crate::grid::cube_offsets;
use crate::stages::band::Band;
use crate::stages::vertex_side::Side;
use crate::stages::voxelize::Voxelization;
use rayon::prelude::*;

/// Smallest difference of |w| between two regions for one to be nested in the other: half
/// the step of one closed surface.
pub const NESTED_STEP: f64 = 0.5;

/// The rule for surfaces between two solid regions, prepared once per conversion: which
/// enclosed region each end of a crossed grid edge between two inside vertices lies in, and
/// which regions are *wholly nested*.
///
/// A region is wholly nested when the surfaces around it separate it (through crossed grid
/// edges between inside vertices) from exactly one other solid region, of a winding number
/// lower by at least [`NESTED_STEP`], and from nothing else (no crossed edge leads from it to
/// an outside vertex, and no outside vertex lies within [`NESTED_CLEARANCE`] of it): a solid
/// modelled entirely inside another (a sphere in a sphere), whose surface bounds no material
/// and is not kept. Where two closed parts only
/// overlap (a leg pushed into a body), the overlap is separated from two regions (the leg's
/// own inside and the body's), and the surfaces inside it are the parts' own: they stay, as
/// thin sheets inside the solid, as without the rule. Removing them cut each part back to what
/// shows outside the other, which lost parts and recall on the dev corpus (docs/ALGORITHM.md
/// §6).
#[derive(Debug, Clone, Default)]
pub struct Nesting {
    /// Per core band vertex: its solid enclosed region if it is an inside end of a crossed
    /// edge between two inside vertices, else [`NO_REGION`]. Empty when no two solid regions
    /// differ enough to be nested.
    region: Vec<u32>,
    /// Per region: wholly nested in another.
    wholly: Vec<bool>,
    /// Per region: its median |w|.
    winding: Vec<f64>,
}

/// Distance, in grid steps per axis, from the inside ends of a nested region's crossed edges
/// within which no vertex may be outside for the region to be wholly nested. Where an inner
/// solid reaches the other's wall or pokes out of it by less than the grid resolves, the part
/// outside holds no enclosed cell, so no crossed edge leads from the region to an outside
/// vertex, yet removing the region's surface removes what shows outside too, with the open
/// pieces (decals, caps) lying on it. On the dev corpus `Airport_Pushback_Forklift.glb` kept
/// 90 of 96 components at 512³ with the rule unguarded, 92 with 2 steps, 95 with 3, 96 (as
/// without the inside test) with 4 (docs/QUALITY.md, issue 15).
pub const NESTED_CLEARANCE: i64 = 4;

/// The wholly nested regions (of `region`, per band vertex) with an outside vertex within
/// [`NESTED_CLEARANCE`] steps per axis of an end of one of `edges` in them; a region may
/// appear more than once.
fn near_outside(
    band: &Band,
    side: &[Side],
    edges: &[Edge],
    region: &[u32],
    wholly: &[bool],
) -> Vec<u32> {
    edges
        .par_iter()
        .flat_map_iter(|&(i, j, v, u)| [(i, v), (j, u)])
        .filter_map(|(i, c)| {
            let r = region[i as usize];
            if r == NO_REGION || !wholly[r as usize] {
                return None;
            }
            cube_offsets(NESTED_CLEARANCE)
                .any(|off| {
                    let q: [i64; 3] = std::array::from_fn(|a| c[a] + off[a]);
                    band.verts
                        .id(q)
                        .is_some_and(|k| side[k as usize] == Side::Outside)
                })
                .then_some(r)
        })
        .collect()
}

/// Calls `f(v, u)` for every crossed grid edge (from `v` to `u` = `v` + one step along an
/// axis) whose lower end `v` lies in a brick `near` holds (indexed by `walls`' brick keys),
/// brick by brick in parallel, and gathers what it returns.
fn map_blocked_edges<T: Send>(
    vox: &Voxelization,
    near: &[bool],
    f: impl Fn([i64; 3], [i64; 3], &mut Vec<T>) + Sync,
) -> Vec<T> {
    let index = &vox.walls.index;
    vox.blocked
        .par_iter()
        .enumerate()
        .flat_map(|(axis, set)| {
            (0..set.keys.len())
                .into_par_iter()
                .filter(move |&s| {
                    let b = set.index.coord(set.keys[s] as usize);
                    (0..3).all(|a| b[a] < index.dims[a]) && near[index.key(b)]
                })
                .map(move |s| (axis, set, s))
        })
        .flat_map_iter(|(axis, set, s)| {
            let mut out = Vec::new();
            set.for_each_member(s, |v| {
                let mut u = v;
                u[axis] += 1;
                f(v, u, &mut out);
            });
            out
        })
        .collect()
}

impl Nesting {
    /// Finds the regions at the ends of crossed edges between inside vertices and the wholly
    /// nested regions (`side`: every band vertex's side, none `Unknown`). Costs nothing unless
    /// two solid regions differ by [`NESTED_STEP`] or more.
    pub fn new(band: &Band, vox: &Voxelization, side: &[Side], regions: &Regions) -> Self {
        let Some(inner) = inner_candidates(regions) else {
            return Self::default();
        };
        // The edges on an inner region's surface lie within a brick of its cells
        // (`region_at` looks at most REGION_SEARCH + 1 < 8 cells away): the crossed edges
        // elsewhere (most of the surface) separate no nested pair and are skipped.
        let near_inner = regions.bricks_near(&vox.walls, &inner);
        let edges = inside_edges(band, vox, side, &near_inner);
        let region = end_regions(band, vox, side.len(), regions, &edges);
        let winding = regions.winding.clone();
        let mut wholly = nested_once(&edges, &region, &winding);
        // A region near an outside vertex may poke out of the other through a part too thin
        // for enclosed cells: not wholly inside it.
        if wholly.contains(&true) {
            for r in near_outside(band, side, &edges, &region, &wholly) {
                wholly[r as usize] = false;
            }
        }
        // A region with a crossed edge to an outside vertex is not wholly inside another.
        if wholly.contains(&true) {
            for r in touching_outside(band, vox, side, regions, &wholly) {
                wholly[r as usize] = false;
            }
        }
        Self {
            region,
            wholly,
            winding,
        }
    }

    /// Whether the crossed grid edge between band vertices `i` and `j` (both inside) is on
    /// the surface of a wholly nested region, where it meets the one region it is nested in.
    #[inline]
    pub fn separates(&self, i: u32, j: u32) -> bool {
        if self.region.is_empty() {
            return false;
        }
        let (a, b) = (self.region[i as usize], self.region[j as usize]);
        if a == NO_REGION || b == NO_REGION || a == b {
            return false;
        }
        let (wa, wb) = (self.winding[a as usize], self.winding[b as usize]);
        let inner = if wa > wb { a } else { b };
        (wa - wb).abs() >= NESTED_STEP && self.wholly[inner as usize]
    }
}

/// A crossed grid edge between two band vertices: their numbers and coordinates.
type Edge = (u32, u32, [i64; 3], [i64; 3]);

/// Per region, whether it can be the inner one of a nested pair: solid and at least
/// [`NESTED_STEP`] above the lowest solid region; `None` when no two solid regions differ by
/// that much.
fn inner_candidates(regions: &Regions) -> Option<Vec<bool>> {
    let solid = |r: u32| regions.verdicts[r as usize] == Verdict::Solid;
    let (lo, hi) = (0..regions.verdicts.len() as u32)
        .filter(|&r| solid(r))
        .map(|r| regions.winding[r as usize])
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), w| {
            (lo.min(w), hi.max(w))
        });
    if hi - lo < NESTED_STEP {
        return None;
    }
    Some(
        (0..regions.verdicts.len() as u32)
            .map(|r| solid(r) && regions.winding[r as usize] - lo >= NESTED_STEP)
            .collect(),
    )
}

/// The crossed edges between two inside vertices whose lower end lies in a brick `near`
/// holds.
fn inside_edges(band: &Band, vox: &Voxelization, side: &[Side], near: &[bool]) -> Vec<Edge> {
    map_blocked_edges(vox, near, |v, u, out| {
        if let (Some(i), Some(j)) = (band.verts.id(v), band.verts.id(u)) {
            if side[i as usize] == Side::Inside && side[j as usize] == Side::Inside {
                out.push((i, j, v, u));
            }
        }
    })
}

/// Per band vertex (of `vertices`), the solid region an end of one of `edges` lies in
/// ([`Regions::region_at`]), else [`NO_REGION`]; each end looked up once.
fn end_regions(
    band: &Band,
    vox: &Voxelization,
    vertices: usize,
    regions: &Regions,
    edges: &[Edge],
) -> Vec<u32> {
    let mut ends: Vec<(u32, [i64; 3])> = edges
        .par_iter()
        .flat_map_iter(|&(i, j, v, u)| [(i, v), (j, u)])
        .collect();
    ends.par_sort_unstable();
    ends.dedup();
    let found: Vec<u32> = ends
        .par_iter()
        .map(|&(_, c)| {
            regions
                .region_at(band, vox, c)
                .filter(|&r| regions.verdicts[r as usize] == Verdict::Solid)
                .unwrap_or(NO_REGION)
        })
        .collect();
    let mut region = vec![NO_REGION; vertices];
    for (&(i, _), &r) in ends.iter().zip(&found) {
        region[i as usize] = r;
    }
    region
}

/// Per region (of `winding`), whether `edges` separate it from exactly one region, lower by
/// [`NESTED_STEP`] or more (`region` per band vertex).
fn nested_once(edges: &[Edge], region: &[u32], winding: &[f64]) -> Vec<bool> {
    // (higher region, lower region) for every edge between regions nested one in the other.
    let mut pairs: Vec<(u32, u32)> = edges
        .par_iter()
        .filter_map(|&(i, j, _, _)| {
            let (a, b) = (region[i as usize], region[j as usize]);
            if a == NO_REGION || b == NO_REGION {
                return None;
            }
            let (wa, wb) = (winding[a as usize], winding[b as usize]);
            if wa - wb >= NESTED_STEP {
                Some((a, b))
            } else if wb - wa >= NESTED_STEP {
                Some((b, a))
            } else {
                None
            }
        })
        .collect();
    pairs.par_sort_unstable();
    pairs.dedup();
    let mut wholly = vec![false; winding.len()];
    for group in pairs.chunk_by(|a, b| a.0 == b.0) {
        wholly[group[0].0 as usize] = group.len() == 1;
    }
    wholly
}

/// The `wholly` nested regions with a crossed edge from one of their cells to an outside
/// vertex (a region may appear more than once). Only edges within a brick of such a region's
/// cells can lead from it (`region_at` looks at most REGION_SEARCH + 1 < 8 cells away): most
/// of the surface's crossed edges are skipped without a region look-up.
fn touching_outside(
    band: &Band,
    vox: &Voxelization,
    side: &[Side],
    regions: &Regions,
    wholly: &[bool],
) -> Vec<u32> {
    let near = regions.bricks_near(&vox.walls, wholly);
    map_blocked_edges(vox, &near, |v, u, out| {
        let (Some(i), Some(j)) = (band.verts.id(v), band.verts.id(u)) else {
            return;
        };
        let inner = match (side[i as usize], side[j as usize]) {
            (Side::Inside, Side::Outside) => v,
            (Side::Outside, Side::Inside) => u,
            _ => return,
        };
        if let Some(r) = regions.region_at(band, vox, inner) {
            if wholly[r as usize] {
                out.push(r);
            }
        }
    })
}
