//! A triangle cut into the cells it crosses: for each cell, the piece of the triangle inside
//! it, as its area and the barycentric coordinates of its centroid.
//!
//! The triangle is clipped to each x slab of one cell's width it spans, the result to each y
//! slab, that to each z slab (Sutherland–Hodgman against two planes per slab), so the work is
//! proportional to the cells the triangle really crosses, never to its bounding box. Each
//! polygon vertex carries its barycentric coordinates, which are affine in position, so the
//! area-weighted centroid of a piece comes with its own.

use crate::vec3::{cross, norm, sub, Vec3};

/// A polygon vertex: position (grid coordinates) and barycentric coordinates.
type Vertex = [f64; 6];

/// A vertex's position.
fn position(v: Vertex) -> Vec3 {
    [v[0], v[1], v[2]]
}

/// A convex polygon of at most [`MAX`] vertices (a triangle cut by six planes has at most 9).
#[derive(Clone, Copy)]
struct Poly {
    n: usize,
    v: [Vertex; MAX],
}

const MAX: usize = 12;

impl Poly {
    fn empty() -> Self {
        Self {
            n: 0,
            v: [[0.0; 6]; MAX],
        }
    }

    fn push(&mut self, v: Vertex) {
        if self.n < MAX {
            self.v[self.n] = v;
            self.n += 1;
        }
    }

    /// The part with `sign · (x[axis] − at) ≥ 0`.
    fn clip(&self, axis: usize, at: f64, sign: f64) -> Poly {
        let mut out = Poly::empty();
        for i in 0..self.n {
            let (a, b) = (self.v[i], self.v[(i + 1) % self.n]);
            let (da, db) = (sign * (a[axis] - at), sign * (b[axis] - at));
            if da >= 0.0 {
                out.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                let t = da / (da - db);
                out.push(std::array::from_fn(|k| a[k] + t * (b[k] - a[k])));
            }
        }
        out
    }

    /// The part inside the slab `at ≤ x[axis] ≤ at + 1`.
    fn slab(&self, axis: usize, at: f64) -> Poly {
        self.clip(axis, at, 1.0).clip(axis, at + 1.0, -1.0)
    }

    /// Smallest and largest cell index along `axis` the polygon reaches.
    fn span(&self, axis: usize) -> (i64, i64) {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in &self.v[..self.n] {
            lo = lo.min(v[axis]);
            hi = hi.max(v[axis]);
        }
        (lo.floor() as i64, hi.floor() as i64)
    }

    /// Area and area-weighted centroid's barycentric coordinates (fan from the first vertex).
    fn area_centroid(&self) -> (f64, [f64; 3]) {
        let (mut area, mut c) = (0.0, [0.0; 3]);
        if self.n < 3 {
            return (0.0, c);
        }
        let p = &self.v[..self.n];
        for i in 1..self.n - 1 {
            let (a, b, d) = (p[0], p[i], p[i + 1]);
            let (pa, pb, pd) = (position(a), position(b), position(d));
            let s = 0.5 * norm(cross(sub(pb, pa), sub(pd, pa)));
            area += s;
            for k in 0..3 {
                c[k] += s * (a[3 + k] + b[3 + k] + d[3 + k]) / 3.0;
            }
        }
        if area > 0.0 {
            c = c.map(|x| x / area);
        }
        (area, c)
    }
}

/// The triangle as a polygon whose vertices carry their barycentric coordinates.
fn polygon(tri: [[f64; 3]; 3]) -> Poly {
    let mut poly = Poly::empty();
    for (k, p) in tri.iter().enumerate() {
        let mut b = [0.0; 3];
        b[k] = 1.0;
        poly.push([p[0], p[1], p[2], b[0], b[1], b[2]]);
    }
    poly
}

/// The first and last x slice (cell index) the triangle `tri` reaches: the slices
/// [`for_each_piece`] visits.
pub fn x_span(tri: [[f64; 3]; 3]) -> (i64, i64) {
    polygon(tri).span(0)
}

/// Calls `piece(cell, area, barycentric)` for every cell (integer grid coordinates of its
/// minimum corner) the triangle `tri` (grid coordinates) crosses with a positive area, in
/// x, y, z order: the cells' keys rise.
pub fn for_each_piece(tri: [[f64; 3]; 3], piece: impl FnMut([i64; 3], f64, [f64; 3])) {
    for_each_piece_in(tri, (i64::MIN, i64::MAX), piece);
}

/// As [`for_each_piece`], for the cells whose x slice is within `xs` (first, last) only.
/// Each slice's pieces are cut from the whole triangle, so they are the same pieces
/// [`for_each_piece`] gives there.
pub fn for_each_piece_in(
    tri: [[f64; 3]; 3],
    xs: (i64, i64),
    mut piece: impl FnMut([i64; 3], f64, [f64; 3]),
) {
    let poly = polygon(tri);
    let (x0, x1) = poly.span(0);
    for x in x0.max(xs.0)..=x1.min(xs.1) {
        let px = poly.slab(0, x as f64);
        let (y0, y1) = px.span(1);
        for y in y0..=y1 {
            let py = px.slab(1, y as f64);
            let (z0, z1) = py.span(2);
            for z in z0..=z1 {
                let (area, bary) = py.slab(2, z as f64).area_centroid();
                if area > 0.0 {
                    piece([x, y, z], area, bary);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pieces_add_up_to_the_triangle() {
        let tri = [[0.3, 0.2, 0.7], [4.9, 1.1, 2.2], [1.5, 3.8, 0.4]];
        let (mut area, mut c) = (0.0, [0.0; 3]);
        let mut cells = 0;
        for_each_piece(tri, |_, a, b| {
            area += a;
            for k in 0..3 {
                c[k] += a * b[k];
            }
            cells += 1;
        });
        let u = [4.6, 0.9, 1.5];
        let w = [1.2, 3.6, -0.3];
        let x: [f64; 3] = [
            u[1] * w[2] - u[2] * w[1],
            u[2] * w[0] - u[0] * w[2],
            u[0] * w[1] - u[1] * w[0],
        ];
        let exact = 0.5 * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
        assert!((area - exact).abs() < 1e-9 * exact, "{area} vs {exact}");
        // The area-weighted centroid of the pieces is the triangle's: (1/3, 1/3, 1/3).
        for k in 0..3 {
            assert!((c[k] / area - 1.0 / 3.0).abs() < 1e-9, "{c:?}");
        }
        assert!(cells > 5);
    }

    #[test]
    fn pieces_in_a_range_of_slices_are_the_whole_triangles_pieces_there() {
        let tri = [[0.3, 0.2, 0.7], [7.9, 1.1, 2.2], [1.5, 3.8, 6.4]];
        let mut all = Vec::new();
        for_each_piece(tri, |cell, a, b| all.push((cell, a, b)));
        assert_eq!(x_span(tri), (0, 7));
        for xs in [(0, 0), (2, 4), (6, 20), (-3, 1)] {
            let mut some = Vec::new();
            for_each_piece_in(tri, xs, |cell, a, b| some.push((cell, a, b)));
            let expected: Vec<_> = all
                .iter()
                .copied()
                .filter(|(c, _, _)| c[0] >= xs.0 && c[0] <= xs.1)
                .collect();
            assert!(!some.is_empty());
            assert_eq!(some, expected, "slices {xs:?}");
        }
    }

    #[test]
    fn a_triangle_inside_one_cell_is_one_piece() {
        let tri = [[2.1, 3.1, 4.1], [2.9, 3.2, 4.3], [2.4, 3.8, 4.9]];
        let mut seen = Vec::new();
        for_each_piece(tri, |cell, _, _| seen.push(cell));
        assert_eq!(seen, [[2, 3, 4]]);
    }
}
