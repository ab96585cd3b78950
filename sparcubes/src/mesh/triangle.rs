//! One triangle: the closest point on it to a point (Ericson's routine), which the band's
//! distances, the closest-point tree and the tests all measure with.

use crate::vec3::{dot, sub};

/// `a + s·d`.
#[inline]
fn madd(a: [f64; 3], s: f64, d: [f64; 3]) -> [f64; 3] {
    [a[0] + s * d[0], a[1] + s * d[1], a[2] + s * d[2]]
}

/// Closest point to `p` on triangle `abc` (Ericson, "Real-Time Collision Detection", §5.1.5).
/// A triangle of zero area (collinear or repeated corners) gives the closest point of its
/// three edges.
#[inline]
pub fn closest_point_on_triangle(p: [f64; 3], t: &[[f64; 3]; 3]) -> [f64; 3] {
    let [a, b, c] = *t;
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return madd(a, d1 / (d1 - d3), ab);
    }
    let cp = sub(p, c);
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return madd(a, d2 / (d2 - d6), ac);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return madd(b, (d4 - d3) / ((d4 - d3) + (d5 - d6)), sub(c, b));
    }
    let sum = va + vb + vc;
    if !(sum > 0.0 && sum.is_finite()) {
        return closest_point_on_edges(p, t);
    }
    let denom = 1.0 / sum;
    madd(madd(a, vb * denom, ab), vc * denom, ac)
}

/// Closest point to `p` on the three edges of `abc` (the fallback for a degenerate triangle).
fn closest_point_on_edges(p: [f64; 3], t: &[[f64; 3]; 3]) -> [f64; 3] {
    let mut best = t[0];
    let mut best_d2 = f64::INFINITY;
    for k in 0..3 {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        let ab = sub(b, a);
        let len2 = dot(ab, ab);
        let s = if len2 > 0.0 {
            (dot(sub(p, a), ab) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = madd(a, s, ab);
        let d = sub(p, q);
        let d2 = dot(d, d);
        if d2 < best_d2 {
            best_d2 = d2;
            best = q;
        }
    }
    best
}
