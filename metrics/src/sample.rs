//! Deterministic area-weighted point sampling on a triangle mesh.
//!
//! Every sample draws its random numbers from a counter-based hash of `(seed, stream, index)`,
//! so the samples do not depend on the thread count or on the order of evaluation.

use super::geom::{cross, norm, sub, Vec3};
use rayon::prelude::*;

/// Points sampled on a surface, with the unit face normal of the triangle each came from.
#[derive(Debug, Clone, Default)]
pub struct Samples {
    /// Sample positions.
    pub points: Vec<Vec3>,
    /// Unit face normal of the sampled triangle, one per point.
    pub normals: Vec<Vec3>,
}

/// Triangles of a mesh in flat form: corner positions, and unit normals and areas per face.
#[derive(Debug, Clone, Default)]
pub struct Faces {
    /// Corner positions, three per triangle.
    pub corners: Vec<[Vec3; 3]>,
    /// Unit normal per triangle (zero for a degenerate triangle).
    pub normals: Vec<Vec3>,
    /// Area per triangle.
    pub areas: Vec<f64>,
}

impl Faces {
    /// Flat triangles from corner positions.
    pub fn new(corners: Vec<[Vec3; 3]>) -> Self {
        let (normals, areas) = corners
            .iter()
            .map(|[a, b, c]| {
                let n = cross(sub(*b, *a), sub(*c, *a));
                let len = norm(n);
                let unit = if len > 0.0 {
                    [n[0] / len, n[1] / len, n[2] / len]
                } else {
                    [0.0; 3]
                };
                (unit, 0.5 * len)
            })
            .unzip();
        Self {
            corners,
            normals,
            areas,
        }
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.corners.len()
    }

    /// Total area of the triangles listed in `subset`.
    pub fn subset_area(&self, subset: &[u32]) -> f64 {
        subset.iter().map(|&t| self.areas[t as usize]).sum()
    }
}

/// SplitMix64 finaliser: a bijective 64-bit mix.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Three uniform numbers in `[0, 1)` for sample `index` of `stream` under `seed`.
pub fn uniforms(seed: u64, stream: u64, index: u64) -> [f64; 3] {
    let base = mix(seed ^ mix(stream.wrapping_mul(0xD1B5_4A32_D192_ED03) ^ mix(index)));
    let unit = |k: u64| (mix(base ^ k) >> 11) as f64 / (1u64 << 53) as f64;
    [unit(1), unit(2), unit(3)]
}

/// Samples `count` points uniformly by area on the triangles listed in `subset`, with random
/// numbers from `(seed, stream)`. Returns no point when the subset has no area.
pub fn sample_subset(
    faces: &Faces,
    subset: &[u32],
    count: usize,
    seed: u64,
    stream: u64,
) -> Samples {
    let mut cumulative = Vec::with_capacity(subset.len());
    let mut total = 0.0f64;
    for &t in subset {
        total += faces.areas[t as usize];
        cumulative.push(total);
    }
    if total <= 0.0 || !total.is_finite() || count == 0 {
        return Samples::default();
    }
    let (points, normals) = (0..count as u64)
        .into_par_iter()
        .map(|i| {
            let [u0, u1, u2] = uniforms(seed, stream, i);
            let target = u0 * total;
            let k = cumulative
                .partition_point(|&c| c <= target)
                .min(subset.len() - 1);
            let t = subset[k] as usize;
            (
                point_in_triangle(&faces.corners[t], u1, u2),
                faces.normals[t],
            )
        })
        .unzip();
    Samples { points, normals }
}

/// The point of triangle `[a, b, c]` for uniform numbers `u1`, `u2` (uniform by area).
fn point_in_triangle([a, b, c]: &[Vec3; 3], u1: f64, u2: f64) -> Vec3 {
    let r = u1.sqrt();
    let (wa, wb, wc) = (1.0 - r, r * (1.0 - u2), r * u2);
    [
        wa * a[0] + wb * b[0] + wc * c[0],
        wa * a[1] + wb * b[1] + wc * c[1],
        wa * a[2] + wb * b[2] + wc * c[2],
    ]
}
