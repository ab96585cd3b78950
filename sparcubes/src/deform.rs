//! Stage 6: the signed distance and the deformation of every band vertex.
//!
//! Paper step 3 moves each vertex along the distance gradient, x′ = x − η·φ·∇φ. With φ = ±UDF
//! (or UDF − t on a shell) and ∇UDF = (x − p)/UDF for the closest point p, the step moves the
//! vertex straight towards (or, inside a shell, away from) the surface, and the distance at
//! the new position is known exactly without a new query: p stays the closest point along that
//! segment. The step is clamped per axis below half a voxel, so no two vertices swap order and
//! no cell inverts, and it never crosses the zero level set, so signs (and the topology of the
//! extracted mesh) are the same with and without deformation.

use crate::band::Band;
use crate::params::Params;
use crate::sign::{Side, Signs};
use rayon::prelude::*;

/// Signed distance and displacement per band vertex.
#[derive(Debug, Clone)]
pub struct Field {
    /// φ at the (displaced) vertex, voxels; negative inside.
    pub sdf: Vec<f32>,
    /// Displacement, voxels.
    pub deformation: Vec<[f32; 3]>,
}

/// Smallest stored |φ|, voxels. A φ of exactly 0 at a vertex would put the crossing points of
/// all its edges at the vertex itself: distinct output vertices at one position, a pinch.
pub const MIN_ABS_SDF: f64 = 1e-4;

#[inline]
fn signed(udf: f64, side: Side, thin: bool, t: f64) -> f32 {
    let phi = match (side == Side::Inside, thin) {
        (false, false) => udf,
        (true, false) => -udf,
        (false, true) => udf - t,
        (true, true) => t - udf,
    };
    // φ = 0 counts as outside, as in extraction.
    if phi < 0.0 {
        phi.min(-MIN_ABS_SDF) as f32
    } else {
        phi.max(MIN_ABS_SDF) as f32
    }
}

/// Computes φ and δ for every band vertex.
pub fn compute_field(band: &Band, signs: &Signs, params: &Params) -> Field {
    let coords = band.verts.coords();
    let t = params.shell_half_thickness as f64;
    let eta = if params.deform {
        params.deform_step as f64
    } else {
        0.0
    };
    let max = params.deform_max as f64;
    let (sdf, deformation): (Vec<f32>, Vec<[f32; 3]>) = (0..coords.len())
        .into_par_iter()
        .map(|i| {
            let d = band.udf[i] as f64;
            let (side, thin) = (signs.side[i], signs.thin[i]);
            let level = if thin { t } else { 0.0 };
            if eta == 0.0 || d < 1e-6 {
                return (signed(d, side, thin, t), [0.0; 3]);
            }
            let c = coords[i];
            let p = band.closest[i];
            // Unit vector from the surface towards the vertex.
            let u: [f64; 3] = std::array::from_fn(|a| (c[a] as f64 - p[a] as f64) / d);
            let umax = u.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(1e-12);
            let step = (eta * (d - level)).clamp(-max / umax, max / umax);
            let moved = d - step;
            let delta = [
                (-step * u[0]) as f32,
                (-step * u[1]) as f32,
                (-step * u[2]) as f32,
            ];
            (signed(moved, side, thin, t), delta)
        })
        .unzip();
    Field { sdf, deformation }
}
