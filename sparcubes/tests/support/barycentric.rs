//! Barycentric coordinates by the areas of the sub-triangles: the independent reference's
//! way (no shared code with `sparcubes::attributes`), used by the reference check in
//! `tests/attributes_known.rs` and by `examples/attributes_reference.rs`.

/// Twice the area of the triangle `a`, `b`, `c`.
pub fn doubled_area(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let w = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let x = [
        u[1] * w[2] - u[2] * w[1],
        u[2] * w[0] - u[0] * w[2],
        u[0] * w[1] - u[1] * w[0],
    ];
    (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt()
}

/// Barycentric coordinates of `p` in `tri` by the areas of the sub-triangles.
pub fn barycentric_by_areas(p: [f64; 3], tri: [[f64; 3]; 3]) -> [f64; 3] {
    let area = doubled_area;
    let whole = area(tri[0], tri[1], tri[2]);
    if whole.is_nan() || whole <= 0.0 {
        return [1.0 / 3.0; 3];
    }
    [
        area(p, tri[1], tri[2]) / whole,
        area(tri[0], p, tri[2]) / whole,
        area(tri[0], tri[1], p) / whole,
    ]
}
