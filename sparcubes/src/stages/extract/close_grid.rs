//! Completing a sparse grid whose active set ends where the surface does not, as a decoded
//! grid may (a VAE's pruned prediction): every grid vertex gets a sign, so that marching cubes
//! over all cells with a sign change gives a closed, 2-manifold surface by construction.
//!
//! The missing vertices (grid vertices not in `coords`) fall into regions, connected through
//! their grid edges. A region that reaches the border of the grid is outside; an enclosed one
//! takes the sign most of the active vertices next to it have (outside on a tie), as the
//! region is the far side of a band whose near side the grid stored. Missing vertices that end
//! up next to an active vertex of the other sign are added with φ = ±`fill` (no deformation),
//! and so are the cells with a sign change. Active vertices on the grid's border that are
//! inside are set to +`fill` (the grid has nothing beyond them), and counted.
//!
//! Memory: one byte per grid vertex, `(N + 1)³` bytes (17 MB at 256³, 135 MB at 512³).

use crate::grid::cubes::SparseCubes;
use std::collections::VecDeque;

/// What [`close_grid`] changed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CloseStats {
    /// Vertices added (missing before, now a corner of a cell with a sign change).
    pub added_vertices: u64,
    /// Inside vertices added (from enclosed regions whose neighbours are mostly inside).
    pub added_inside: u64,
    /// Cells with a sign change after closing, against `cubes.cells.len()` before.
    pub cells: u64,
    /// Active vertices on the grid's border that were inside and were set outside.
    pub border_clamped: u64,
}

const MISSING: u8 = 0;
const ACTIVE_IN: u8 = 1;
const ACTIVE_OUT: u8 = 2;
const FILLED_IN: u8 = 3;
const FILLED_OUT: u8 = 4;

fn inside(state: u8) -> bool {
    state == ACTIVE_IN || state == FILLED_IN
}

/// The grid completed as the module says; `fill` (voxels, > 0) is the magnitude of φ given to
/// added vertices. Its extraction ([`crate::extract()`]) is closed and 2-manifold.
pub fn close_grid(cubes: &SparseCubes, fill: f32) -> (SparseCubes, CloseStats) {
    let n = cubes.resolution as usize;
    let m = n + 1;
    let at = |c: [usize; 3]| (c[0] * m + c[1]) * m + c[2];
    let on_border = |c: [usize; 3]| c.iter().any(|&x| x == 0 || x == n);
    let mut stats = CloseStats::default();
    let mut state = vec![MISSING; m * m * m];
    let mut sdf = cubes.sdf.clone();
    for (i, c) in cubes.coords.iter().enumerate() {
        let c = c.map(usize::from);
        if c.iter().any(|&x| x > n) {
            continue;
        }
        if sdf[i] < 0.0 && on_border(c) {
            sdf[i] = fill;
            stats.border_clamped += 1;
        }
        state[at(c)] = if sdf[i] < 0.0 { ACTIVE_IN } else { ACTIVE_OUT };
    }
    label_missing_regions(&mut state, m);

    // Cells with a sign change all have an active corner (the corners of a cell are joined by
    // its edges, so corners that are all missing lie in one region, of one sign).
    let mut cells: Vec<[u16; 3]> = Vec::new();
    for c in &cubes.coords {
        let c = c.map(usize::from);
        for d in 0..8usize {
            let off = [d & 1, d >> 1 & 1, d >> 2];
            if (0..3).any(|a| c[a] < off[a] || c[a] - off[a] >= n) {
                continue;
            }
            let cell = [c[0] - off[0], c[1] - off[1], c[2] - off[2]];
            let corner_inside = |k: usize| {
                inside(
                    state[at([
                        cell[0] + (k & 1),
                        cell[1] + (k >> 1 & 1),
                        cell[2] + (k >> 2),
                    ])],
                )
            };
            let ins = (0..8).filter(|&k| corner_inside(k)).count();
            if ins > 0 && ins < 8 {
                cells.push(cell.map(|x| x as u16));
            }
        }
    }
    cells.sort_unstable();
    cells.dedup();
    stats.cells = cells.len() as u64;

    let mut corners: Vec<[u16; 3]> = cells
        .iter()
        .flat_map(|c| {
            (0..8u16).map(move |k| [c[0] + (k & 1), c[1] + (k >> 1 & 1), c[2] + (k >> 2)])
        })
        .collect();
    corners.sort_unstable();
    corners.dedup();
    let mut out = SparseCubes {
        resolution: cubes.resolution,
        normalization: cubes.normalization,
        coords: Vec::with_capacity(corners.len()),
        sdf: Vec::with_capacity(corners.len()),
        deformation: Vec::with_capacity(corners.len()),
        cells,
    };
    for c in corners {
        let s = state[at(c.map(usize::from))];
        let (phi, delta) = match cubes.vertex_index(c) {
            Some(i) if s == ACTIVE_IN || s == ACTIVE_OUT => (
                sdf[i],
                cubes.deformation.get(i).copied().unwrap_or([0.0; 3]),
            ),
            _ => {
                stats.added_vertices += 1;
                if s == FILLED_IN {
                    stats.added_inside += 1;
                    (-fill, [0.0; 3])
                } else {
                    (fill, [0.0; 3])
                }
            }
        };
        out.coords.push(c);
        out.sdf.push(phi);
        out.deformation.push(delta);
    }
    (out, stats)
}

/// Gives every missing vertex of `state` (an `m³` grid) the sign of its region: outside when
/// the region reaches the grid's border, else the majority sign of the active vertices next
/// to it (outside on a tie).
fn label_missing_regions(state: &mut [u8], m: usize) {
    let at = |c: [usize; 3]| (c[0] * m + c[1]) * m + c[2];
    let coord = |i: usize| [i / (m * m), i / m % m, i % m];
    let mut queue = VecDeque::new();
    let mut region = Vec::new();
    for start in 0..state.len() {
        if state[start] != MISSING {
            continue;
        }
        // Mark the region as visited (FILLED_OUT for now) while collecting it.
        state[start] = FILLED_OUT;
        queue.push_back(start);
        region.clear();
        let (mut border, mut votes_in, mut votes_out) = (false, 0u64, 0u64);
        while let Some(i) = queue.pop_front() {
            region.push(i);
            let c = coord(i);
            for axis in 0..3 {
                for up in [false, true] {
                    let mut d = c;
                    if up {
                        if c[axis] + 1 >= m {
                            border = true;
                            continue;
                        }
                        d[axis] += 1;
                    } else {
                        if c[axis] == 0 {
                            border = true;
                            continue;
                        }
                        d[axis] -= 1;
                    }
                    let j = at(d);
                    match state[j] {
                        MISSING => {
                            state[j] = FILLED_OUT;
                            queue.push_back(j);
                        }
                        ACTIVE_IN => votes_in += 1,
                        ACTIVE_OUT => votes_out += 1,
                        _ => {}
                    }
                }
            }
        }
        if !border && votes_in > votes_out {
            for &i in &region {
                state[i] = FILLED_IN;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::topology;
    use crate::shapes;

    fn sphere_cubes(n: u32) -> SparseCubes {
        let params = crate::Params {
            resolution: n,
            ..Default::default()
        };
        crate::convert(&shapes::sphere([0.0; 3], 1.0, 48), &params)
            .map(|c| c.cubes)
            .unwrap_or_default()
    }

    #[test]
    fn closing_a_converted_grid_leaves_its_surface_as_it_was() {
        let cubes = sphere_cubes(32);
        assert!(!cubes.cells.is_empty());
        let (closed, stats) = close_grid(&cubes, 0.5);
        assert_eq!(stats.border_clamped, 0);
        let before = crate::extract(&cubes);
        let after = crate::extract(&closed);
        assert_eq!(after.triangles.len(), before.triangles.len(), "{stats:?}");
        assert!(topology::check(&after).is_closed_oriented_manifold());
    }

    #[test]
    fn a_grid_with_cells_and_vertices_missing_extracts_closed_after_closing() {
        let mut cubes = sphere_cubes(32);
        // Drop every seventh cell and every eleventh vertex, as a noisy decoder might.
        let keep: Vec<usize> = (0..cubes.coords.len()).filter(|i| i % 11 != 3).collect();
        cubes.coords = keep.iter().map(|&i| cubes.coords[i]).collect();
        cubes.sdf = keep.iter().map(|&i| cubes.sdf[i]).collect();
        cubes.deformation = keep.iter().map(|&i| cubes.deformation[i]).collect();
        cubes.cells = cubes
            .cells
            .iter()
            .enumerate()
            .filter(|(i, _)| i % 7 != 2)
            .map(|(_, c)| *c)
            .collect();
        let open = topology::check(&crate::extract(&cubes));
        assert!(
            !open.is_closed_oriented_manifold(),
            "the damaged grid should extract open"
        );
        let (closed, stats) = close_grid(&cubes, 0.5);
        let mesh = crate::extract(&closed);
        let t = topology::check(&mesh);
        assert!(t.is_closed_oriented_manifold(), "{t:?} {stats:?}");
        assert!(stats.added_vertices > 0);
        assert!(mesh.triangles.len() > 1000);
    }

    #[test]
    fn an_enclosed_missing_region_takes_the_sign_of_its_neighbours() {
        // A solid ball of inside vertices with a missing core: the core is inside, so no
        // inner surface appears.
        let n = 12u32;
        let mut cubes = SparseCubes {
            resolution: n,
            ..Default::default()
        };
        for x in 0..=n as u16 {
            for y in 0..=n as u16 {
                for z in 0..=n as u16 {
                    let d = [x, y, z].map(|v| v as f32 - 6.0);
                    let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                    if r < 1.5 {
                        continue; // the missing core
                    }
                    if r < 5.5 {
                        cubes.coords.push([x, y, z]);
                        cubes.sdf.push(r - 4.0);
                        cubes.deformation.push([0.0; 3]);
                    }
                }
            }
        }
        let (closed, stats) = close_grid(&cubes, 0.5);
        let mesh = crate::extract(&closed);
        let t = topology::check(&mesh);
        assert!(t.is_closed_oriented_manifold(), "{t:?}");
        // Labelled outside, the core would have grown a second, inner surface.
        assert_eq!(t.components, 1, "{t:?} {stats:?}");
    }
}
