//! A dual vertex per active cell (a cell with a crossed edge), as flexible dual grids and dual
//! contouring place them (Ju et al., "Dual Contouring of Hermite Data", 2002): the point of
//! the closed cell that minimises the squared distances to the planes of the cell's triangles
//! plus `regularization` × (number of crossings) × the squared distance to the mean of the
//! crossing points on the cell's edges; with, per cell, which of the three edges through its
//! upper corner the surface crosses (a sign change of φ between their ends).
//!
//! The triangles and crossing points are those of our extraction ([`crate::extract()`]), so
//! the vertices follow the watertight surface.

use super::corners::chunks_with_corners;
use crate::grid::cubes::SparseCubes;
use crate::stages::extract::mc_table::EDGES;
use crate::stages::extract::{cell_triangles_at, CellEdgePoints};
use crate::vec3::{cross, dot, norm, sub};
use rayon::prelude::*;

/// The dual vertices of one item's active cells.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DualVertices {
    /// Active cells by minimum corner, sorted.
    pub cells: Vec<[u16; 3]>,
    /// Dual vertex of each cell in cell-local coordinates, in [0, 1]³.
    pub vertices: Vec<[f32; 3]>,
    /// Per cell, the surface crossing the edges through its upper corner `(1, 1, 1)`: bit 0
    /// the edge along x (from `(0, 1, 1)`), bit 1 along y (from `(1, 0, 1)`), bit 2 along z
    /// (from `(1, 1, 0)`); a sign change of φ between the edge's ends.
    pub crossed: Vec<u8>,
}

/// The dual vertices of `cubes` with the pull towards the mean crossing point weighted by
/// `regularization` per crossing (cells whose corners are not all stored are skipped). Built a
/// chunk of cells at a time, each chunk's rows into its own vectors of known size, joined in
/// order at the end.
pub fn dual_vertices(cubes: &SparseCubes, regularization: f64) -> DualVertices {
    let parts: Vec<DualVertices> = chunks_with_corners(cubes)
        .map_init(Vec::new, |tris, (cells, corners)| {
            let mut part = DualVertices::with_capacity(cells.len());
            for (&c, idx) in cells.iter().zip(corners) {
                let vertex = idx.and_then(|idx| dual_vertex(cubes, c, &idx, regularization, tris));
                if let Some((v, flags)) = vertex {
                    part.push(c, v, flags);
                }
            }
            part
        })
        .collect();
    let mut out = DualVertices::with_capacity(parts.iter().map(|p| p.cells.len()).sum());
    for p in parts {
        out.cells.extend(p.cells);
        out.vertices.extend(p.vertices);
        out.crossed.extend(p.crossed);
    }
    out
}

impl DualVertices {
    /// Empty, with room for `n` cells.
    fn with_capacity(n: usize) -> Self {
        Self {
            cells: Vec::with_capacity(n),
            vertices: Vec::with_capacity(n),
            crossed: Vec::with_capacity(n),
        }
    }

    /// Appends cell `c` with its dual vertex `v` (cell-local) and crossed-edge `flags`.
    fn push(&mut self, c: [u16; 3], v: [f32; 3], flags: u8) {
        self.cells.push(c);
        self.vertices.push(v);
        self.crossed.push(flags);
    }
}

/// The dual vertex (cell-local) and crossed-edge flags of cell `c` with corners `idx`, or
/// `None` when no edge of it is crossed; `tris` is scratch space for the cell's triangles.
fn dual_vertex(
    cubes: &SparseCubes,
    c: [u16; 3],
    idx: &[usize; 8],
    regularization: f64,
    tris: &mut Vec<[[f64; 3]; 3]>,
) -> Option<([f32; 3], u8)> {
    let inside = idx.map(|i| cubes.sdf[i] < 0.0);
    let flags = u8::from(inside[6] != inside[7])
        | (u8::from(inside[5] != inside[7]) << 1)
        | (u8::from(inside[3] != inside[7]) << 2);
    let origin = c.map(f64::from);
    let local = |p: [f64; 3]| sub(p, origin);
    let mut edges = CellEdgePoints::new(cubes, idx);
    let (mut a, mut b) = plane_quadric(&mut edges, &local, tris);
    let mut mean = [0.0; 3];
    let mut count = 0.0;
    for (e, &(u, v, _)) in EDGES.iter().enumerate() {
        if inside[u as usize] != inside[v as usize] {
            let p = local(edges.get(e as u8));
            mean = std::array::from_fn(|k| mean[k] + p[k]);
            count += 1.0;
        }
    }
    if count == 0.0 {
        return None;
    }
    let mean = mean.map(|m| m / count);
    let w = regularization * count;
    for i in 0..3 {
        a[i][i] += w;
        b[i] += w * mean[i];
    }
    let v = minimize_in_unit_box(&a, &b);
    Some((v.map(|x| x as f32), flags))
}

/// The quadric `xᵀAx − 2bᵀx` (as `(A, b)`, cell-local through `local`) summing the squared
/// distances to the planes of the triangles of the cell whose crossing points `edges` holds;
/// degenerate triangles add nothing.
fn plane_quadric(
    edges: &mut CellEdgePoints,
    local: &impl Fn([f64; 3]) -> [f64; 3],
    tris: &mut Vec<[[f64; 3]; 3]>,
) -> ([[f64; 3]; 3], [f64; 3]) {
    let mut a = [[0.0f64; 3]; 3];
    let mut b = [0.0f64; 3];
    tris.clear();
    cell_triangles_at(edges, tris);
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
    (a, b)
}

/// The minimiser of `xᵀAx − 2bᵀx` (A symmetric positive definite) over `[0, 1]³`. A
/// strictly convex quadric has one minimiser, the stationary point of one face of the box
/// (each axis free, at 0 or at 1) where the gradient points out of the box on the fixed axes
/// (the KKT conditions). Tried in turn: the whole quadric's stationary point when it lies
/// inside; the face that clamping it points to, when the conditions hold there (most cells);
/// else the best feasible stationary point among all 27 faces.
fn minimize_in_unit_box(a: &[[f64; 3]; 3], b: &[f64; 3]) -> [f64; 3] {
    if let Some(x) = face_stationary_point(a, b, [Face::Free; 3]) {
        if x.iter().all(|v| *v > 0.0 && *v < 1.0) {
            return x;
        }
        let guess = x.map(|v| match v {
            v if v < 0.0 => Face::Zero,
            v if v > 1.0 => Face::One,
            _ => Face::Free,
        });
        if let Some(y) = face_stationary_point(a, b, guess) {
            if feasible(&y) && points_out(a, b, &y, guess) {
                return y.map(|v| v.clamp(0.0, 1.0));
            }
        }
    }
    best_face_point(a, b)
}

/// How a face of the unit box holds one axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Face {
    /// Not held.
    Free,
    /// At 0.
    Zero,
    /// At 1.
    One,
}

/// Whether `x` lies in the closed unit box (to rounding).
fn feasible(x: &[f64; 3]) -> bool {
    x.iter().all(|v| (-1e-12..=1.0 + 1e-12).contains(v))
}

/// Whether the gradient of the quadric at `x` points out of the box on every axis `how` holds
/// (non-negative where held at 0, non-positive at 1): then `x` is the box's minimiser.
fn points_out(a: &[[f64; 3]; 3], b: &[f64; 3], x: &[f64; 3], how: [Face; 3]) -> bool {
    (0..3).all(|i| {
        let g: f64 = (0..3).map(|j| a[i][j] * x[j]).sum::<f64>() - b[i];
        match how[i] {
            Face::Free => true,
            Face::Zero => g >= -1e-12,
            Face::One => g <= 1e-12,
        }
    })
}

/// The best feasible stationary point among the 27 faces of the box, by the quadric's value;
/// the box's centre when none is feasible (A singular on every face, which a positive
/// definite A never is).
fn best_face_point(a: &[[f64; 3]; 3], b: &[f64; 3]) -> [f64; 3] {
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
    let faces = [Face::Free, Face::Zero, Face::One];
    let mut best: Option<(f64, [f64; 3])> = None;
    for code in 0..27usize {
        let how = [faces[code % 3], faces[code / 3 % 3], faces[code / 9]];
        let Some(x) = face_stationary_point(a, b, how).filter(feasible) else {
            continue;
        };
        let x = x.map(|v| v.clamp(0.0, 1.0));
        let f = value(&x);
        if best.is_none_or(|(bf, _)| f < bf) {
            best = Some((f, x));
        }
    }
    best.map_or([0.5; 3], |(_, x)| x)
}

/// The stationary point of the quadric on the face `how` (the held axes at their values, the
/// free ones solving `A_ff x_f = b_f − A_fh x_h`), or `None` when that system is singular.
fn face_stationary_point(a: &[[f64; 3]; 3], b: &[f64; 3], how: [Face; 3]) -> Option<[f64; 3]> {
    let mut x = how.map(|h| if h == Face::One { 1.0 } else { 0.0 });
    let mut free_axes = [0usize; 3];
    let mut k = 0;
    for i in (0..3).filter(|&i| how[i] == Face::Free) {
        free_axes[k] = i;
        k += 1;
    }
    let free = &free_axes[..k];
    let mut m = [[0.0f64; 4]; 3];
    for (r, &i) in free.iter().enumerate() {
        for (s, &j) in free.iter().enumerate() {
            m[r][s] = a[i][j];
        }
        m[r][k] = b[i]
            - (0..3)
                .filter(|&j| how[j] != Face::Free)
                .map(|j| a[i][j] * x[j])
                .sum::<f64>();
    }
    let sol = solve(&m, k)?;
    for (r, &i) in free.iter().enumerate() {
        x[i] = sol[r];
    }
    Some(x)
}

/// The solution of the `k × k` system whose augmented matrix is `m` (`k ≤ 3`, the right-hand
/// side in column `k`), by Cramer's rule; `None` when its determinant is (nearly) zero.
fn solve(m: &[[f64; 4]; 3], k: usize) -> Option<[f64; 3]> {
    let det2 = |a: f64, b: f64, c: f64, d: f64| a * d - b * c;
    match k {
        0 => Some([0.0; 3]),
        1 => (m[0][0].abs() >= 1e-14).then(|| [m[0][1] / m[0][0], 0.0, 0.0]),
        2 => {
            let d = det2(m[0][0], m[0][1], m[1][0], m[1][1]);
            (d.abs() >= 1e-14).then(|| {
                [
                    det2(m[0][2], m[0][1], m[1][2], m[1][1]) / d,
                    det2(m[0][0], m[0][2], m[1][0], m[1][2]) / d,
                    0.0,
                ]
            })
        }
        _ => {
            let det3 = |c: [usize; 3]| {
                m[0][c[0]] * det2(m[1][c[1]], m[1][c[2]], m[2][c[1]], m[2][c[2]])
                    - m[0][c[1]] * det2(m[1][c[0]], m[1][c[2]], m[2][c[0]], m[2][c[2]])
                    + m[0][c[2]] * det2(m[1][c[0]], m[1][c[1]], m[2][c[0]], m[2][c[1]])
            };
            let d = det3([0, 1, 2]);
            (d.abs() >= 1e-14).then(|| {
                [
                    det3([3, 1, 2]) / d,
                    det3([0, 3, 2]) / d,
                    det3([0, 1, 3]) / d,
                ]
            })
        }
    }
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
    fn the_kkt_shortcut_finds_the_best_face_point() {
        // Random positive definite quadrics whose minimum lies anywhere around the box: the
        // shortcut must give what trying all 27 faces gives.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut shortcuts = 0;
        for _ in 0..20_000 {
            let m: [[f64; 3]; 3] = std::array::from_fn(|_| std::array::from_fn(|_| next() - 0.5));
            let mut a = [[0.0; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    a[i][j] = (0..3).map(|k| m[k][i] * m[k][j]).sum::<f64>();
                }
                a[i][i] += 0.01;
            }
            let b: [f64; 3] = std::array::from_fn(|_| 4.0 * next() - 2.0);
            let fast = minimize_in_unit_box(&a, &b);
            let full = best_face_point(&a, &b);
            let dist = (0..3)
                .map(|i| (fast[i] - full[i]).abs())
                .fold(0.0, f64::max);
            assert!(dist < 1e-9, "{a:?} {b:?}: {fast:?} vs {full:?}");
            shortcuts += usize::from(fast.iter().any(|v| *v == 0.0 || *v == 1.0));
        }
        assert!(shortcuts > 1000, "{shortcuts} minima on the box's faces");
    }

    #[test]
    fn dual_vertices_inside_cells_and_flags_match_sign_changes() {
        for mesh in [
            sphere([0.0; 3], 0.5, 24),
            cuboid([-0.5; 3], [0.4, 0.3, 0.2], &[]),
        ] {
            let cubes = crate::convert(&mesh, &Params::with_resolution(32))
                .unwrap_or_else(|e| panic!("{e}"))
                .cubes;
            let g = dual_vertices(&cubes, 1e-2);
            assert_eq!(g.cells, cubes.cells);
            let sign: HashMap<[u16; 3], bool> = cubes
                .coords
                .iter()
                .zip(&cubes.sdf)
                .map(|(c, s)| (*c, *s < 0.0))
                .collect();
            let mut flagged = 0;
            for ((c, v), f) in g.cells.iter().zip(&g.vertices).zip(&g.crossed) {
                assert!(v.iter().all(|x| (0.0..=1.0).contains(x)), "{c:?}: {v:?}");
                let corner = |dx: u16, dy: u16, dz: u16| sign[&[c[0] + dx, c[1] + dy, c[2] + dz]];
                let expect = u8::from(corner(0, 1, 1) != corner(1, 1, 1))
                    | (u8::from(corner(1, 0, 1) != corner(1, 1, 1)) << 1)
                    | (u8::from(corner(1, 1, 0) != corner(1, 1, 1)) << 2);
                assert_eq!(*f, expect, "{c:?}");
                flagged += f.count_ones();
            }
            // Every crossed grid edge is flagged by exactly one cell (its lower cell in the
            // other two axes) when that cell is active: count them independently.
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
