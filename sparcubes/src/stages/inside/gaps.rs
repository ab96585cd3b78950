//! Thin parts the grid cannot hold: where a grid edge crosses a found part with both ends
//! outside ([`parts_with_gaps`]), the exact field would leave a hole, so the part goes back to
//! the thin shell.

use crate::grid::{cube_offsets, dilate, BrickSet, Dilation};
use crate::stages::band::Band;
use crate::stages::vertex_side::Side;
use crate::stages::voxelize::Voxelization;
use rayon::prelude::*;

/// Marker of a band vertex that is not sealed, in a position list ([`Sealed::position`]).
pub(super) const NOT_SEALED: u32 = u32::MAX;

/// The sealed vertices as `decide_sealed` found them: per band vertex its position among
/// them ([`NOT_SEALED`] if none), and per position its coordinates, whether the winding
/// number found it inside, and its thin part.
pub(super) struct Sealed<'a> {
    pub(super) position: &'a [u32],
    pub(super) coords: &'a [[u32; 3]],
    pub(super) found: &'a [bool],
    pub(super) part_of: &'a [u32],
}

/// Whether the grid edge from `v` to `u`, both outside and crossed by the surface, passes
/// through something thinner than the edge — its ends see their closest surface points on
/// opposite sides (directions more than 120° apart) — rather than clipping a corner or a rim
/// (directions about 90° apart or less). An end closer than 10⁻³ voxel to the surface has no
/// reliable direction and does not count.
fn crosses_a_sheet(band: &Band, v: [i64; 3], u: [i64; 3]) -> bool {
    let away = |c: [i64; 3]| -> Option<[f64; 3]> {
        let near = band.nearest[band.verts.id(c)? as usize];
        (near.udf > 1e-3).then(|| std::array::from_fn(|a| c[a] as f64 - near.point[a] as f64))
    };
    match (away(v), away(u)) {
        (Some(a), Some(b)) => {
            let (la, lb) = (crate::vec3::dot(a, a).sqrt(), crate::vec3::dot(b, b).sqrt());
            crate::vec3::dot(a, b) < -0.5 * la * lb
        }
        _ => false,
    }
}

/// Which thin parts a grid edge crosses through something thinner than itself with both ends
/// outside ([`crosses_a_sheet`]) next to one of their vertices (`side` holds every other
/// vertex's side; the sealed ones are still `Unknown`).
pub(super) fn parts_with_gaps(
    band: &Band,
    vox: &Voxelization,
    side: &[Side],
    sealed: &Sealed,
    parts: usize,
    n: u32,
) -> Vec<bool> {
    let Sealed {
        position,
        coords,
        found,
        part_of,
    } = *sealed;
    let mut too_thin = vec![false; parts];
    if parts == 0 {
        return too_thin;
    }
    // The found vertices and their 26 neighbours, to test edges against cheaply.
    let index = crate::grid::BrickIndex::for_resolution(n);
    let mut packed: Vec<u64> = coords
        .iter()
        .zip(found)
        .filter(|(_, &f)| f)
        .map(|(&c, _)| crate::grid::pack(&index, c))
        .collect();
    packed.sort_unstable();
    let near = dilate(&BrickSet::from_sorted_packed(n, &packed), n, Dilation::Box);
    let outside = |c: [i64; 3]| -> bool {
        band.verts.id(c).is_some_and(|i| match side[i as usize] {
            Side::Outside => true,
            Side::Unknown => !found[position[i as usize] as usize],
            Side::Inside => false,
        })
    };
    // The crossed edges with an end in `near`, found from `near`'s side (it is far smaller
    // than the crossed edges of the whole surface), brick by brick in parallel.
    let marks: Vec<u32> = (0..near.keys.len())
        .into_par_iter()
        .flat_map_iter(|s| {
            let mut out = Vec::new();
            near.for_each_member(s, |w| {
                for axis in 0..3 {
                    for lower in [true, false] {
                        let (mut v, mut u) = (w, w);
                        if lower {
                            u[axis] += 1;
                        } else {
                            v[axis] -= 1;
                        }
                        // An edge with both ends in `near` is seen from its lower end only.
                        if !lower && near.contains(v) {
                            continue;
                        }
                        if !vox.blocked[axis].contains(v) || !outside(v) || !outside(u) {
                            continue;
                        }
                        if !crosses_a_sheet(band, v, u) {
                            continue;
                        }
                        for end in [v, u] {
                            for off in cube_offsets(1) {
                                let c: [i64; 3] = std::array::from_fn(|a| end[a] + off[a]);
                                let Some(j) = band.verts.id(c) else {
                                    continue;
                                };
                                let q = position[j as usize];
                                if q != NOT_SEALED && found[q as usize] {
                                    out.push(part_of[q as usize]);
                                }
                            }
                        }
                    }
                }
            });
            out
        })
        .collect();
    for p in marks {
        too_thin[p as usize] = true;
    }
    too_thin
}
