//! Float arrays in a consumer's precision, and the rows consumers pack samples into
//! (`[x, y, z, nx, ny, nz]`, `[x, y, z, d]`), moved by a [`Placement`].

use crate::npz::Array;
use crate::Placement;

/// The float width a consumer stores.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Width {
    /// IEEE half (`<f2`).
    F16,
    /// IEEE single (`<f4`).
    F32,
}

/// An array of `values` (row-major, `shape`) stored at `width`.
pub(crate) fn floats(name: &str, shape: Vec<usize>, values: &[f64], width: Width) -> Array {
    match width {
        Width::F16 => {
            let h: Vec<u16> = values
                .iter()
                .map(|&x| half::f16::from_f64(x).to_bits())
                .collect();
            Array::numbers(name, "<f2", shape, &h)
        }
        Width::F32 => {
            let f: Vec<f32> = values.iter().map(|&x| x as f32).collect();
            Array::numbers(name, "<f4", shape, &f)
        }
    }
}

/// Points moved by `place`, flattened (`n × 3`).
pub(crate) fn placed(points: &[[f32; 3]], place: &Placement) -> Vec<f64> {
    points.iter().flat_map(|&p| place.point(p)).collect()
}

/// Rows `[x, y, z, nx, ny, nz]`: points moved by `place`, their unit normals as they are (a
/// similarity keeps directions).
pub(crate) fn point_normal_rows(
    points: &[[f32; 3]],
    normals: &[[f32; 3]],
    place: &Placement,
) -> Vec<f64> {
    points
        .iter()
        .zip(normals)
        .flat_map(|(&p, &n)| {
            let q = place.point(p);
            [q[0], q[1], q[2], n[0] as f64, n[1] as f64, n[2] as f64]
        })
        .collect()
}

/// Rows `[x, y, z, d]`: points moved by `place` with their distance scaled and multiplied by
/// `sign` (−1 for consumers whose distance is positive inside; ours is negative inside).
pub(crate) fn point_distance_rows(
    points: &[[f32; 3]],
    distances: &[f32],
    place: &Placement,
    sign: f64,
) -> Vec<f64> {
    points
        .iter()
        .zip(distances)
        .flat_map(|(&p, &d)| {
            let q = place.point(p);
            [q[0], q[1], q[2], sign * place.distance(d)]
        })
        .collect()
}
