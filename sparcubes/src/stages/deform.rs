//! Stage 8: the signed distance and the deformation of every band vertex.
//!
//! Paper step 3 moves each vertex along the distance gradient, x′ = x − η·φ·∇φ. With φ = ±UDF
//! (or UDF − t on a shell) and ∇UDF = (x − p)/UDF for the closest point p, the step moves the
//! vertex straight towards (or, inside a shell, away from) the surface, and the distance at
//! the new position is known exactly without a new query: p stays the closest point along that
//! segment. The step is clamped per axis below half a voxel, so no two vertices swap order and
//! no cell inverts, and it never crosses the zero level set, so signs (and the topology of the
//! extracted mesh) are the same with and without deformation.

use crate::params::Params;
use crate::stages::band::{Band, Nearest};
use crate::stages::sign::Signs;
use crate::stages::vertex_side::Side;

/// Signed distance and displacement per band vertex.
#[derive(Debug, Clone)]
pub struct Field {
    /// φ at the (displaced) vertex, voxels; negative inside.
    pub sdf: Vec<f32>,
    /// Displacement, voxels; empty when deformation is off (every displacement is zero).
    pub deformation: Vec<[f32; 3]>,
}

impl Field {
    /// Displacement of vertex `i` (zero when deformation is off).
    #[inline]
    pub fn deformation_at(&self, i: usize) -> [f32; 3] {
        self.deformation.get(i).copied().unwrap_or([0.0; 3])
    }
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
    let t = params.shell_half_thickness as f64;
    let eta = if params.deform {
        params.deform_step as f64
    } else {
        0.0
    };
    let max = params.deform_max as f64;
    let n = band.verts.len;
    let mut sdf = vec![0f32; n];
    let mut deformation = Vec::new();
    let vertex = |i: usize, c: [u32; 3]| -> (f32, [f32; 3]) {
        let Nearest { point: p, udf } = band.nearest[i];
        let d = udf as f64;
        let (side, thin) = (signs.side[i], signs.thin[i]);
        let level = if thin { t } else { 0.0 };
        if eta == 0.0 || d < 1e-6 {
            return (signed(d, side, thin, t), [0.0; 3]);
        }
        // Unit vector from the surface towards the vertex.
        let u: [f64; 3] = std::array::from_fn(|a| (c[a] as f64 - p[a] as f64) / d);
        let umax = u.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(1e-12);
        let step = (eta * (d - level)).clamp(-max / umax, max / umax);
        let delta = [
            (-step * u[0]) as f32,
            (-step * u[1]) as f32,
            (-step * u[2]) as f32,
        ];
        (signed(d - step, side, thin, t), delta)
    };
    band.verts.par_fill_each(&mut sdf, |i, c| vertex(i, c).0);
    if eta > 0.0 {
        deformation = vec![[0f32; 3]; n];
        band.verts
            .par_fill_each(&mut deformation, |i, c| vertex(i, c).1);
    }
    Field { sdf, deformation }
}
