//! Small vector helpers and the closest point on a triangle (Ericson, "Real-Time Collision
//! Detection", §5.1.5), which also says which feature (face, edge, corner) it lies on.

pub use sparcubes::vec3::{add, cross, dist2, dot, norm, scale, sub, Vec3};

/// Where on a triangle its closest point to a query lies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Feature {
    /// Inside the face.
    Face,
    /// On the edge from corner `k` to corner `(k + 1) % 3`.
    Edge(u8),
    /// At corner `k`.
    Corner(u8),
}

/// The closest point of triangle `[a, b, c]` to `p`, and the feature it lies on.
pub fn closest_on_triangle(p: Vec3, [a, b, c]: &[Vec3; 3]) -> (Vec3, Feature) {
    let ab = sub(*b, *a);
    let ac = sub(*c, *a);
    let ap = sub(p, *a);
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (*a, Feature::Corner(0));
    }
    let bp = sub(p, *b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (*b, Feature::Corner(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (add(*a, scale(ab, v)), Feature::Edge(0));
    }
    let cp = sub(p, *c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (*c, Feature::Corner(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (add(*a, scale(ac, w)), Feature::Edge(2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (add(*b, scale(sub(*c, *b), w)), Feature::Edge(1));
    }
    let denom = va + vb + vc;
    if denom == 0.0 || !denom.is_finite() {
        // Degenerate triangle that no region test caught: fall back to its first corner.
        return (*a, Feature::Corner(0));
    }
    let (v, w) = (vb / denom, vc / denom);
    (add(*a, add(scale(ab, v), scale(ac, w))), Feature::Face)
}
