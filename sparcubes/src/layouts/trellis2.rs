//! TRELLIS.2's flexible dual grid (O-Voxel, `o-voxel/src/convert/flexible_dual_grid.cpp` and
//! `data_toolkit/dual_grid.py` of microsoft/TRELLIS.2), computed from our surface:
//!
//! - the voxels are the active cells (every cell with a crossed edge; TRELLIS.2 activates the
//!   four voxels around each crossed grid line, the same set);
//! - the dual vertex minimises a quadric error inside the voxel: the squared distances to the
//!   planes of the voxel's triangles plus `REGULARIZATION` × (number of crossings) × the
//!   squared distance to the mean of the crossing points on the voxel's edges (TRELLIS.2's
//!   face term with weight 1 and regularisation 1e-2), minimised over the closed voxel;
//! - it is stored as `floor(255 · (v − voxel))` per axis, 3 × `u8` (TRELLIS.2 clamps to
//!   [0, 1], scales by 255 and casts to `uint8`);
//! - `intersected` bit `a` (1, 2, 4 for x, y, z) says whether the surface crosses the voxel's
//!   grid edge along axis `a` at its upper corner in the other two axes (the edge whose four
//!   voxels TRELLIS.2 joins into a quad): for x the edge (0,1,1)–(1,1,1), for y (1,0,1)–(1,1,1),
//!   for z (1,1,0)–(1,1,1), i.e. a sign change of φ between those corners.

use super::cells_with_corners;
use crate::cubes::SparseCubes;
use crate::extract::{cell_triangles, edge_point};
use crate::mc_table::EDGES;
use crate::vec3::{cross, dot, norm, sub};
use rayon::prelude::*;

/// Weight of the pull towards the mean crossing point, per crossing (TRELLIS.2's
/// `regularization_weight=1e-2` in `data_toolkit/dual_grid.py`).
pub const REGULARIZATION: f64 = 1e-2;

/// TRELLIS.2's flexible dual grid of one item.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DualGrid {
    /// Active voxels (cells) by minimum corner, sorted.
    pub voxels: Vec<[u16; 3]>,
    /// Dual vertex of each voxel in voxel-local coordinates, in [0, 1]³ (before quantisation).
    pub vertices: Vec<[f32; 3]>,
    /// Quantised dual vertices: `floor(255 · local)`.
    pub quantized: Vec<[u8; 3]>,
    /// Intersected flags: bit 0 x, bit 1 y, bit 2 z (module docs).
    pub intersected: Vec<u8>,
}

/// The flexible dual grid of `cubes` (cells whose corners are not all stored are skipped).
pub fn dual_grid(cubes: &SparseCubes) -> DualGrid {
    let rows: Vec<([u16; 3], [f32; 3], u8)> = cells_with_corners(cubes)
        .map_init(Vec::new, |tris, (c, idx)| {
            let idx = idx?;
            let inside = idx.map(|i| cubes.sdf[i] < 0.0);
            let flags = u8::from(inside[6] != inside[7])
                | (u8::from(inside[5] != inside[7]) << 1)
                | (u8::from(inside[3] != inside[7]) << 2);
            let origin = c.map(f64::from);
            let local = |p: [f64; 3]| sub(p, origin);
            // Quadric f(x) = xᵀAx − 2bᵀx, in voxel-local coordinates.
            let mut a = [[0.0f64; 3]; 3];
            let mut b = [0.0f64; 3];
            tris.clear();
            cell_triangles(cubes, &idx, tris);
            for t in tris.iter() {
                let [p0, p1, p2] = t.map(local);
                let n = cross(sub(p1, p0), sub(p2, p0));
                let l = norm(n);
                if !(l > 0.0 && l.is_finite()) {
                    continue;
                }
                let n = n.map(|v| v / l);
                let d = dot(n, p0);
                for i in 0..3 {
                    b[i] += d * n[i];
                    for j in 0..3 {
                        a[i][j] += n[i] * n[j];
                    }
                }
            }
            let mut mean = [0.0; 3];
            let mut count = 0.0;
            for (e, &(u, v, _)) in EDGES.iter().enumerate() {
                if inside[u as usize] != inside[v as usize] {
                    let p = local(edge_point(cubes, &idx, e as u8));
                    mean = std::array::from_fn(|k| mean[k] + p[k]);
                    count += 1.0;
                }
            }
            if count == 0.0 {
                return None;
            }
            let mean = mean.map(|m| m / count);
            let w = REGULARIZATION * count;
            for i in 0..3 {
                a[i][i] += w;
                b[i] += w * mean[i];
            }
            let v = minimize_in_unit_box(&a, &b);
            Some((c, v.map(|x| x as f32), flags))
        })
        .flatten()
        .collect();
    let mut out = DualGrid::default();
    for (c, v, f) in rows {
        out.voxels.push(c);
        out.quantized.push(v.map(quantize));
        out.vertices.push(v);
        out.intersected.push(f);
    }
    out
}

/// TRELLIS.2's quantisation of a local coordinate: clamp to [0, 1], scale by 255, truncate.
#[inline]
pub fn quantize(x: f32) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0) as u8
}

/// The minimiser of `xᵀAx − 2bᵀx` (A symmetric positive definite) over `[0, 1]³`: the best
/// feasible stationary point among the 27 faces of the box (each axis free, at 0 or at 1).
/// For a convex quadric the minimum lies at the stationary point of one of them.
fn minimize_in_unit_box(a: &[[f64; 3]; 3], b: &[f64; 3]) -> [f64; 3] {
    let value = |x: &[f64; 3]| -> f64 {
        let mut f = 0.0;
        for i in 0..3 {
            f -= 2.0 * b[i] * x[i];
            for j in 0..3 {
                f += x[i] * a[i][j] * x[j];
            }
        }
        f
    };
    let mut best: Option<(f64, [f64; 3])> = None;
    for code in 0..27u32 {
        // Per axis: 0 free, 1 fixed at 0, 2 fixed at 1.
        let how = [code % 3, code / 3 % 3, code / 9];
        let mut x = [0.0; 3];
        let mut free_axes = [0usize; 3];
        let mut k = 0;
        for i in (0..3).filter(|&i| how[i] == 0) {
            free_axes[k] = i;
            k += 1;
        }
        let free = &free_axes[..k];
        for i in 0..3 {
            if how[i] == 2 {
                x[i] = 1.0;
            }
        }
        // Solve A_ff x_f = b_f − A_fc x_c for the free axes.
        let mut m = [[0.0f64; 4]; 3];
        for (r, &i) in free.iter().enumerate() {
            for (s, &j) in free.iter().enumerate() {
                m[r][s] = a[i][j];
            }
            m[r][k] = b[i]
                - (0..3)
                    .filter(|j| how[*j] != 0)
                    .map(|j| a[i][j] * x[j])
                    .sum::<f64>();
        }
        let Some(sol) = solve(&mut m, k) else {
            continue;
        };
        for (r, &i) in free.iter().enumerate() {
            x[i] = sol[r];
        }
        if x.iter().all(|v| (-1e-12..=1.0 + 1e-12).contains(v)) {
            // A strictly interior stationary point of the whole quadric (code 0) is its
            // minimum: no face can do better, so the other 26 are not tried.
            if code == 0 && x.iter().all(|v| *v > 0.0 && *v < 1.0) {
                return x;
            }
            let x = x.map(|v| v.clamp(0.0, 1.0));
            let f = value(&x);
            if best.is_none_or(|(bf, _)| f < bf) {
                best = Some((f, x));
            }
        }
    }
    best.map_or([0.5; 3], |(_, x)| x)
}

/// Gaussian elimination with partial pivoting on the `k × (k + 1)` augmented matrix `m`.
fn solve(m: &mut [[f64; 4]; 3], k: usize) -> Option<[f64; 3]> {
    for col in 0..k {
        let pivot = (col..k).max_by(|&i, &j| m[i][col].abs().total_cmp(&m[j][col].abs()))?;
        if m[pivot][col].abs() < 1e-14 {
            return None;
        }
        m.swap(col, pivot);
        for row in 0..k {
            if row != col {
                let f = m[row][col] / m[col][col];
                for c in col..=k {
                    m[row][c] -= f * m[col][c];
                }
            }
        }
    }
    let mut x = [0.0; 3];
    for i in 0..k {
        x[i] = m[i][k] / m[i][i];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::Params;
    use crate::shapes::{cuboid, sphere};
    use std::collections::HashMap;

    #[test]
    fn box_minimiser_matches_a_grid_search() {
        let cases = [
            (
                [[2.0, 0.3, 0.0], [0.3, 1.0, 0.1], [0.0, 0.1, 0.5]],
                [0.4, -0.7, 1.3],
            ),
            (
                [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                [0.2, 0.5, 0.9],
            ),
            (
                [[1.0, 0.9, 0.0], [0.9, 1.0, 0.0], [0.0, 0.0, 0.01]],
                [2.0, -1.0, 0.3],
            ),
        ];
        for (a, b) in cases {
            let x = minimize_in_unit_box(&a, &b);
            let f = |x: [f64; 3]| -> f64 {
                (0..3)
                    .map(|i| {
                        -2.0 * b[i] * x[i] + (0..3).map(|j| x[i] * a[i][j] * x[j]).sum::<f64>()
                    })
                    .sum()
            };
            let steps = 40;
            let mut grid_best = f64::INFINITY;
            for i in 0..=steps {
                for j in 0..=steps {
                    for k in 0..=steps {
                        let p = [i, j, k].map(|v| v as f64 / steps as f64);
                        grid_best = grid_best.min(f(p));
                    }
                }
            }
            assert!(f(x) <= grid_best + 1e-12, "{x:?}: {} > {grid_best}", f(x));
        }
    }

    #[test]
    fn dual_vertices_inside_voxels_and_flags_match_sign_changes() {
        for mesh in [
            sphere([0.0; 3], 0.5, 24),
            cuboid([-0.5; 3], [0.4, 0.3, 0.2], &[]),
        ] {
            let cubes = crate::convert(&mesh, &Params::with_resolution(32))
                .unwrap_or_else(|e| panic!("{e}"))
                .cubes;
            let g = dual_grid(&cubes);
            assert_eq!(g.voxels, cubes.cells);
            let sign: HashMap<[u16; 3], bool> = cubes
                .coords
                .iter()
                .zip(&cubes.sdf)
                .map(|(c, s)| (*c, *s < 0.0))
                .collect();
            let mut flagged = 0;
            for (((c, v), q), f) in g
                .voxels
                .iter()
                .zip(&g.vertices)
                .zip(&g.quantized)
                .zip(&g.intersected)
            {
                assert!(v.iter().all(|x| (0.0..=1.0).contains(x)), "{c:?}: {v:?}");
                for a in 0..3 {
                    assert_eq!(q[a], (v[a] * 255.0) as u8);
                }
                let corner = |dx: u16, dy: u16, dz: u16| sign[&[c[0] + dx, c[1] + dy, c[2] + dz]];
                let expect = u8::from(corner(0, 1, 1) != corner(1, 1, 1))
                    | (u8::from(corner(1, 0, 1) != corner(1, 1, 1)) << 1)
                    | (u8::from(corner(1, 1, 0) != corner(1, 1, 1)) << 2);
                assert_eq!(*f, expect, "{c:?}");
                flagged += f.count_ones();
            }
            // Every crossed grid edge is flagged by exactly one voxel (its lower voxel in
            // the other two axes) when that voxel is active: count them independently.
            let mut crossed = 0;
            for (c, s) in &sign {
                for a in 0..3 {
                    let mut d = *c;
                    d[a] += 1;
                    if sign.get(&d).is_some_and(|t| t != s) {
                        crossed += 1;
                    }
                }
            }
            assert_eq!(flagged, crossed);
        }
    }
}
