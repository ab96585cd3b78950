//! Marching-cubes triangulation table, generated so that ambiguous faces are resolved the same
//! way from both cells that share them.
//!
//! The table is built once, programmatically, from the cube's faces rather than copied:
//!
//! 1. on each of the 6 faces, segments join the crossing points of that face's edges so that
//!    they separate inside corners from outside corners; on an ambiguous face (corners
//!    alternate in/out) a bit of the key says whether the two inside corners are joined;
//! 2. each segment is oriented with the inside on its right seen from outside the cube, and
//!    the segments are chained into closed loops (every crossing point lies on exactly two
//!    faces, so every loop is a simple cycle);
//! 3. each loop is triangulated by a fan when every diagonal of the fan joins crossing points
//!    whose cube edges share no face (such a diagonal cannot be produced by another cell),
//!    and otherwise around a centre vertex of its own (the mean of the loop's points).
//!
//! Every segment is therefore used once by each of the two cells sharing its face, and every
//! other edge lies inside one cell: the union over a set of cells that contains every cell
//! with a sign change is closed and 2-manifold. Triangles are oriented outwards (from
//! negative to non-negative values).
//!
//! Conventions: corner `i` is at `(i & 1, (i >> 1) & 1, (i >> 2) & 1)`; edge `e` runs along
//! axis `e / 4` from corner [`EDGES`]`[e].0` (lower) to [`EDGES`]`[e].1`; face `f` is
//! perpendicular to axis `f / 2` on side `f % 2`, with corners [`FACE_CORNERS`]`[f]` in
//! cyclic order. A corner is inside when its value is negative (zero counts as outside).

use crate::vec3::{cross, sub};
use std::sync::OnceLock;

/// The 12 cube edges as `(lower corner, upper corner, axis)`; edge `e` has axis `e / 4`.
pub const EDGES: [(u8, u8, u8); 12] = [
    (0, 1, 0),
    (2, 3, 0),
    (4, 5, 0),
    (6, 7, 0),
    (0, 2, 1),
    (1, 3, 1),
    (4, 6, 1),
    (5, 7, 1),
    (0, 4, 2),
    (1, 5, 2),
    (2, 6, 2),
    (3, 7, 2),
];

/// The corners of face `f` (axis `f / 2`, side `f % 2`) in cyclic order, counter-clockwise
/// seen from the positive side of the axis.
pub const FACE_CORNERS: [[u8; 4]; 6] = [
    [0, 2, 6, 4],
    [1, 3, 7, 5],
    [0, 4, 5, 1],
    [2, 6, 7, 3],
    [0, 1, 3, 2],
    [4, 5, 7, 6],
];

/// Face bits that join the inside corners on every ambiguous face: the choice when no value
/// information is available (it keeps thin shells connected).
pub const DEFAULT_FACE_BITS: u8 = 0x3f;

/// Index of the first centre vertex in [`Case::triangles`]; centre `k` is `CENTRE + k`.
pub const CENTRE: u8 = 12;

/// The triangulation of one key (corner mask + face bits).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Case {
    /// Triangles, outward; indices `0..12` are cube edges (their crossing points) and
    /// `CENTRE + k` is the centre vertex `k`.
    pub triangles: Vec<[u8; 3]>,
    /// For each centre vertex, the cube edges whose crossing points it averages.
    pub centres: Vec<Vec<u8>>,
}

/// The full table: one [`Case`] per 8-bit corner mask and 6-bit face-bit set.
#[derive(Debug)]
pub struct Table {
    cases: Vec<Case>,
}

impl Table {
    /// The case of corner mask `mask` (bit `i` set when corner `i` is inside) and face bits
    /// `face_bits` (bit `f` set when the inside corners of face `f` are joined; only read for
    /// ambiguous faces).
    #[inline]
    pub fn case(&self, mask: u8, face_bits: u8) -> &Case {
        let bits = face_bits & ambiguous_faces(mask);
        &self.cases[mask as usize | (bits as usize) << 8]
    }
}

/// The table, built on first use.
pub fn table() -> &'static Table {
    static TABLE: OnceLock<Table> = OnceLock::new();
    TABLE.get_or_init(|| Table {
        cases: (0..1usize << 14)
            .map(|key| {
                let (mask, bits) = ((key & 0xff) as u8, (key >> 8) as u8);
                // Only bits of ambiguous faces are ever looked up.
                if bits & !ambiguous_faces(mask) == 0 {
                    build_case(mask, bits)
                } else {
                    Case::default()
                }
            })
            .collect(),
    })
}

/// The faces of `mask` whose corners alternate inside/outside, as a bit set over faces.
#[inline]
pub fn ambiguous_faces(mask: u8) -> u8 {
    let mut bits = 0;
    for (f, c) in FACE_CORNERS.iter().enumerate() {
        let s = |i: usize| mask >> c[i] & 1;
        if s(0) == s(2) && s(1) == s(3) && s(0) != s(1) {
            bits |= 1 << f;
        }
    }
    bits
}

/// Whether the inside corners of an ambiguous face are joined, by the asymptotic decider on
/// its values in cyclic order: the bilinear saddle value `(ac − bd) / (a + c − b − d)` is
/// negative. Only the sign matters and it is computed exactly (products of `f32` are exact in
/// `f64`), so the two cells sharing the face always agree, whatever the corner order.
#[inline]
pub fn inside_joined(values: [f32; 4]) -> bool {
    let [a, b, c, d] = values.map(f64::from);
    // Inside corners are (a, c) or (b, d); the denominator has the sign of the outside pair
    // minus the inside pair, so a negative saddle means inside product > outside product.
    if a < 0.0 {
        a * c > b * d
    } else {
        b * d > a * c
    }
}

/// Twice the coordinates of corner `c`.
fn corner2(c: u8) -> [i32; 3] {
    [
        2 * (c & 1) as i32,
        2 * (c >> 1 & 1) as i32,
        2 * (c >> 2 & 1) as i32,
    ]
}

/// Twice the coordinates of the midpoint of edge `e`.
fn mid2(e: u8) -> [i32; 3] {
    let (a, b, _) = EDGES[e as usize];
    let (p, q) = (corner2(a), corner2(b));
    [(p[0] + q[0]) / 2, (p[1] + q[1]) / 2, (p[2] + q[2]) / 2]
}

fn edge_between(a: u8, b: u8) -> u8 {
    let (lo, hi) = (a.min(b), a.max(b));
    EDGES
        .iter()
        .position(|&(x, y, _)| x == lo && y == hi)
        .map_or(u8::MAX, |e| e as u8)
}

/// Bit set of the two faces that contain edge `e`.
fn edge_faces(e: u8) -> u8 {
    let (lo, _, axis) = EDGES[e as usize];
    let c = corner2(lo);
    let mut bits = 0;
    for (a, &x) in c.iter().enumerate() {
        if a != axis as usize {
            bits |= 1 << (2 * a + (x / 2) as usize);
        }
    }
    bits
}

/// Shape quality of a triangle: 1 for equilateral, 0 for degenerate.
fn quality(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let n = cross(sub(b, a), sub(c, a));
    let area2 = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let l2 = |u: [f64; 3], v: [f64; 3]| {
        let d = sub(u, v);
        d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    };
    let sum = l2(a, b) + l2(b, c) + l2(c, a);
    if sum > 0.0 {
        2.0 * 3f64.sqrt() * area2 / sum
    } else {
        0.0
    }
}

fn build_case(mask: u8, face_bits: u8) -> Case {
    let inside = |c: u8| mask >> c & 1 == 1;
    // next[e] = the crossing point following e along its loop.
    let mut next = [u8::MAX; 12];
    for (f, fc) in FACE_CORNERS.iter().enumerate() {
        let edges: [u8; 4] = std::array::from_fn(|j| edge_between(fc[j], fc[(j + 1) % 4]));
        let crossing: Vec<usize> = (0..4)
            .filter(|&j| inside(fc[j]) != inside(fc[(j + 1) % 4]))
            .collect();
        let mut segments = Vec::with_capacity(2);
        match crossing.len() {
            2 => segments.push((edges[crossing[0]], edges[crossing[1]])),
            4 => {
                // Cut off the corners that are not joined: the outside ones when the inside
                // corners are joined, the inside ones otherwise. Corner j lies between face
                // edges j − 1 and j.
                let join_inside = face_bits >> f & 1 == 1;
                for j in 0..4 {
                    if inside(fc[j]) != join_inside {
                        segments.push((edges[(j + 3) % 4], edges[j]));
                    }
                }
            }
            _ => {}
        }
        let axis = f / 2;
        let mut normal = [0.0; 3];
        normal[axis] = if f % 2 == 1 { 1.0 } else { -1.0 };
        for (p, q) in segments {
            let (ca, cb, _) = EDGES[p as usize];
            let c = if inside(ca) { ca } else { cb };
            let f64v = |v: [i32; 3]| v.map(f64::from);
            let (pp, qq, cc) = (f64v(mid2(p)), f64v(mid2(q)), f64v(corner2(c)));
            let n = cross(sub(qq, pp), sub(cc, pp));
            let side = n[0] * normal[0] + n[1] * normal[1] + n[2] * normal[2];
            // Inside on the right seen from outside: the loop then runs counter-clockwise
            // around the outward normal of the surface.
            let (from, to) = if side > 0.0 { (q, p) } else { (p, q) };
            debug_assert_eq!(next[from as usize], u8::MAX);
            next[from as usize] = to;
        }
    }

    let mut case = Case::default();
    let mut seen = [false; 12];
    for start in 0..12u8 {
        if seen[start as usize] || next[start as usize] == u8::MAX {
            continue;
        }
        let mut lp = Vec::new();
        let mut e = start;
        while !seen[e as usize] {
            seen[e as usize] = true;
            lp.push(e);
            e = next[e as usize];
        }
        debug_assert_eq!(e, start, "segments must chain into closed loops");
        triangulate_loop(&lp, &mut case);
    }
    case
}

fn triangulate_loop(lp: &[u8], case: &mut Case) {
    let k = lp.len();
    if k == 3 {
        case.triangles.push([lp[0], lp[1], lp[2]]);
        return;
    }
    let pos = |e: u8| mid2(e).map(f64::from);
    let mut best: Option<(f64, usize)> = None;
    for r in 0..k {
        let valid = (2..k - 1).all(|d| edge_faces(lp[r]) & edge_faces(lp[(r + d) % k]) == 0);
        if !valid {
            continue;
        }
        let q = (1..k - 1)
            .map(|i| quality(pos(lp[r]), pos(lp[(r + i) % k]), pos(lp[(r + i + 1) % k])))
            .fold(f64::INFINITY, f64::min);
        if best.is_none_or(|(bq, _)| q > bq) {
            best = Some((q, r));
        }
    }
    match best {
        Some((_, r)) => {
            for i in 1..k - 1 {
                case.triangles
                    .push([lp[r], lp[(r + i) % k], lp[(r + i + 1) % k]]);
            }
        }
        None => {
            let c = CENTRE + case.centres.len() as u8;
            for i in 0..k {
                case.triangles.push([c, lp[i], lp[(i + 1) % k]]);
            }
            case.centres.push(lp.to_vec());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    #[test]
    fn edges_and_faces_are_consistent() {
        for (e, &(a, b, axis)) in EDGES.iter().enumerate() {
            assert_eq!(axis as usize, e / 4);
            assert_eq!(b - a, 1 << axis);
            assert_eq!(edge_faces(e as u8).count_ones(), 2);
        }
        for (f, fc) in FACE_CORNERS.iter().enumerate() {
            for j in 0..4 {
                let c = fc[j];
                assert_eq!((c >> (f / 2)) & 1, (f % 2) as u8);
                assert_ne!(edge_between(c, fc[(j + 1) % 4]), u8::MAX);
            }
        }
    }

    /// Within every case, each boundary edge of the cell's surface lies on a cube face (it is
    /// a segment) and every other edge is used exactly twice, in opposite directions.
    #[test]
    fn every_case_is_locally_closed() {
        let t = table();
        for key in 0..1usize << 14 {
            let (mask, bits) = ((key & 0xff) as u8, (key >> 8) as u8);
            let case = t.case(mask, bits);
            let mut directed: HashMap<(u8, u8), u32> = HashMap::new();
            for tri in &case.triangles {
                assert!(tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2]);
                for i in 0..3 {
                    *directed.entry((tri[i], tri[(i + 1) % 3])).or_default() += 1;
                }
            }
            for (&(a, b), &n) in &directed {
                assert_eq!(
                    n, 1,
                    "mask {mask:#x} bits {bits:#x}: edge {a}-{b} used twice"
                );
                if directed.contains_key(&(b, a)) {
                    continue;
                }
                // An unpaired edge must be a segment on a common cube face.
                assert!(a < CENTRE && b < CENTRE);
                assert_ne!(edge_faces(a) & edge_faces(b), 0);
            }
            let crossings = (0..12)
                .filter(|&e| {
                    let (a, b, _) = EDGES[e];
                    (mask >> a & 1) != (mask >> b & 1)
                })
                .count();
            let used: std::collections::HashSet<u8> = case
                .triangles
                .iter()
                .flatten()
                .copied()
                .filter(|&v| v < CENTRE)
                .collect();
            assert_eq!(used.len(), crossings);
        }
    }

    #[test]
    fn decider_is_symmetric() {
        let v = [-0.3f32, 0.7, -0.9, 0.2];
        let j = inside_joined(v);
        assert_eq!(inside_joined([v[1], v[2], v[3], v[0]]), j);
        assert_eq!(inside_joined([v[3], v[2], v[1], v[0]]), j);
        assert!(inside_joined([-1.0, 0.1, -1.0, 0.1]));
        assert!(!inside_joined([-0.1, 1.0, -0.1, 1.0]));
    }
}
