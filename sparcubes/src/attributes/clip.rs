//! A triangle cut into the cells it crosses: for each cell, the piece of the triangle inside
//! it, as its area and the barycentric coordinates of its centroid.
//!
//! The triangle is clipped to each x slab of one cell's width it spans (Sutherland–Hodgman
//! against the slab's two planes); each slab's polygon is then cut along y, one plane after
//! the next, each cut splitting off the piece below the plane and keeping the rest, and each
//! of those pieces along z the same way. The work is proportional to the cells the triangle
//! really crosses, never to its bounding box, and a cut is skipped where the polygon lies
//! within one slab already (a small triangle costs no cut at all). A piece's area is summed
//! over a fan along the triangle's own unit normal (no square root a piece), its centroid
//! is the fan's area-weighted one, and its barycentric coordinates come from the centroid by
//! the triangle's affine map (they are affine in position, so this is the area-weighted mean
//! of the piece's barycentric coordinates).

use crate::vec3::{add, cross, dot, scale, sub, Vec3};

/// A convex polygon of at most [`MAX`] vertices (grid coordinates). A triangle cut by six
/// planes has at most 9; each cut adds at most one.
#[derive(Clone, Copy)]
struct Poly {
    n: usize,
    v: [Vec3; MAX],
}

const MAX: usize = 10;

impl Poly {
    fn empty() -> Self {
        Self {
            n: 0,
            v: [[0.0; 3]; MAX],
        }
    }

    fn push(&mut self, v: Vec3) {
        if self.n < MAX {
            self.v[self.n] = v;
            self.n += 1;
        }
    }

    /// The point of edge `a`–`b` on the plane `x[axis] = at`, where `a` and `b` are at signed
    /// distances `da` and `db` from it (of opposite signs).
    fn crossing(a: Vec3, b: Vec3, da: f64, db: f64) -> Vec3 {
        let t = da / (da - db);
        std::array::from_fn(|k| a[k] + t * (b[k] - a[k]))
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
                out.push(Self::crossing(a, b, da, db));
            }
        }
        out
    }

    /// The part inside the slab `at ≤ x[axis] ≤ at + 1` (the polygon itself when it spans
    /// one slab only).
    fn slab(&self, axis: usize, at: f64) -> Poly {
        let (lo, hi) = self.span(axis);
        if lo == hi {
            return *self;
        }
        self.clip(axis, at, 1.0).clip(axis, at + 1.0, -1.0)
    }

    /// Writes the parts with `x[axis] ≤ at` to `below` and with `x[axis] ≥ at` to `above`,
    /// in one pass (a vertex on the plane goes to both).
    fn split_into(&self, axis: usize, at: f64, below: &mut Poly, above: &mut Poly) {
        below.n = 0;
        above.n = 0;
        for i in 0..self.n {
            let (a, b) = (self.v[i], self.v[(i + 1) % self.n]);
            let (da, db) = (a[axis] - at, b[axis] - at);
            if da <= 0.0 {
                below.push(a);
            }
            if da >= 0.0 {
                above.push(a);
            }
            if (da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0) {
                let p = Self::crossing(a, b, da, db);
                below.push(p);
                above.push(p);
            }
        }
    }

    /// Calls `each(cell, piece)` for each slab along `axis` the polygon reaches, in rising
    /// order, cutting one plane after the next: each cut splits the piece below the plane off
    /// what is left, both written into buffers that are reused, not copied.
    fn sweep(&self, axis: usize, mut each: impl FnMut(i64, &Poly)) {
        let (first, last) = self.span(axis);
        if first == last {
            each(first, self);
            return;
        }
        let mut piece = Poly::empty();
        // What is left is in `halves[0]` after an even number of cuts, in `halves[1]` after
        // an odd one; each cut writes the next rest into the other.
        let mut halves = [*self, Poly::empty()];
        for k in first..last {
            let [even, odd] = &mut halves;
            let (rest, next) = if (k - first) % 2 == 0 {
                (&*even, odd)
            } else {
                (&*odd, even)
            };
            rest.split_into(axis, (k + 1) as f64, &mut piece, next);
            each(k, &piece);
        }
        each(last, &halves[((last - first) % 2) as usize]);
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

    /// Area along the unit normal `normal` and area-weighted centroid (fan from the first
    /// vertex).
    fn area_centroid(&self, normal: Vec3) -> (f64, Vec3) {
        let (mut area, mut c) = (0.0, [0.0; 3]);
        if self.n < 3 {
            return (0.0, c);
        }
        let p = &self.v[..self.n];
        for i in 1..self.n - 1 {
            let s = 0.5 * dot(normal, cross(sub(p[i], p[0]), sub(p[i + 1], p[0])));
            area += s;
            c = add(c, scale(add(p[0], add(p[i], p[i + 1])), s / 3.0));
        }
        if area > 0.0 {
            c = scale(c, 1.0 / area);
        }
        (area, c)
    }
}

/// A triangle's frame: its first corner, its unit normal, and the two vectors whose dot
/// products with `p − corner` give the barycentric coordinates of corners 1 and 2 at a point
/// `p` of its plane.
struct Frame {
    corner: Vec3,
    normal: Vec3,
    duals: [Vec3; 2],
}

impl Frame {
    /// The frame of `tri`, `None` when it has no area.
    fn new(tri: [[f64; 3]; 3]) -> Option<Self> {
        let (e0, e1) = (sub(tri[1], tri[0]), sub(tri[2], tri[0]));
        let n = cross(e0, e1);
        let n2 = dot(n, n);
        if !(n2 > 0.0 && n2.is_finite()) {
            return None;
        }
        Some(Self {
            corner: tri[0],
            normal: scale(n, 1.0 / n2.sqrt()),
            duals: [scale(cross(e1, n), 1.0 / n2), scale(cross(n, e0), 1.0 / n2)],
        })
    }

    /// Barycentric coordinates of `p` (on the plane).
    fn barycentric(&self, p: Vec3) -> [f64; 3] {
        let d = sub(p, self.corner);
        let (v, w) = (dot(d, self.duals[0]), dot(d, self.duals[1]));
        [1.0 - v - w, v, w]
    }
}

/// The triangle as a polygon.
fn polygon(tri: [[f64; 3]; 3]) -> Poly {
    let mut poly = Poly::empty();
    for p in tri {
        poly.push(p);
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
    let (first, last) = (x0.max(xs.0), x1.min(xs.1));
    if first > last {
        return;
    }
    let Some(frame) = Frame::new(tri) else {
        return;
    };
    for x in first..=last {
        poly.slab(0, x as f64).sweep(1, |y, py| {
            py.sweep(2, |z, pz| {
                let (area, centroid) = pz.area_centroid(frame.normal);
                if area > 0.0 {
                    piece([x, y, z], area, frame.barycentric(centroid));
                }
            });
        });
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
