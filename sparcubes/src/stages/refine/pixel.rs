//! One pixel's loss and its exact gradient with respect to the corners of the triangle its
//! ray hits.
//!
//! The loss of a pixel is the paper's per-pixel term, (D − I_D)² + ‖N − I_N‖² (Sparc3D,
//! §3.2, step 4: L = ‖R_D(M) − I_D‖² + ‖R_N(M) − I_N‖²), with D the depth along the ray to
//! the hit triangle's plane and N its unit normal turned towards the camera. Both are smooth
//! functions of the corners v0, v1, v2 while the ray stays on the same triangle:
//!
//! - depth: the hit point x = o + t·d lies on the plane n·(y − v0) = 0, n = (v1 − v0) ×
//!   (v2 − v0). Moving corner i by ε moves the plane at x by bᵢ·ε (bᵢ: x's barycentric
//!   coordinate), so ∂t/∂vᵢ = bᵢ·n̂/(n̂·d);
//! - normal: N = s·n/‖n‖ (s = ±1, towards the camera), ∂N = s·(I − N̂N̂ᵀ)·∂n/‖n‖, and
//!   ∂n = ∂v1 × e2 − ∂v2 × e1 − ∂v0 × (e2 − e1) gives g·∂n = ∂v1·(e2 × g) + ∂v2·(g × e1)
//!   + ∂v0·(−(e2 × g) − (g × e1)).
//!
//! A pixel whose depth differs from the target's by more than [`MAX_DEPTH_GAP`] sees another
//! surface than the source does there (a part the grid shells or merges): its loss is
//! capped at [`CAPPED_LOSS`] and it pulls on nothing.

use crate::vec3::{add, cross, dot, norm, scale, sub};

/// Largest depth difference, in voxels, at which an output pixel is compared with the source
/// pixel: marching cubes on the exact distance misses a sharp edge by a fraction of a voxel.
pub const MAX_DEPTH_GAP: f64 = 1.0;

/// The loss of a pixel that sees another surface than the source, or none: a depth gap of
/// [`MAX_DEPTH_GAP`] and opposite normals (1 + 4), the most a compared pixel can lose.
pub const CAPPED_LOSS: f64 = MAX_DEPTH_GAP * MAX_DEPTH_GAP + 4.0;

/// What the source shows at a pixel: its depth along the ray and its unit normal, turned
/// towards the camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Target {
    /// Depth along the ray, voxels.
    pub depth: f32,
    /// Unit normal facing the camera.
    pub normal: [f32; 3],
}

/// A ray in voxels: its origin and unit direction.
#[derive(Debug, Clone, Copy)]
pub struct PixelRay {
    /// Origin.
    pub origin: [f64; 3],
    /// Unit direction.
    pub dir: [f64; 3],
}

/// Depth and camera-facing unit normal where `ray` meets the plane of `tri`; `None` when the
/// triangle is degenerate or seen edge-on.
pub fn depth_normal(ray: &PixelRay, tri: &[[f64; 3]; 3]) -> Option<(f64, [f64; 3])> {
    let n = cross(sub(tri[1], tri[0]), sub(tri[2], tri[0]));
    let len = norm(n);
    let nd = dot(n, ray.dir);
    if !len.is_normal() || nd.abs() <= 1e-12 * len {
        return None;
    }
    let t = dot(n, sub(tri[0], ray.origin)) / nd;
    let s = if nd > 0.0 { -1.0 } else { 1.0 };
    Some((t, scale(n, s / len)))
}

/// The loss of one pixel, and its gradient on the three corners of the triangle hit (zero
/// when capped).
pub fn pixel_loss(ray: &PixelRay, tri: &[[f64; 3]; 3], target: &Target) -> (f64, [[f64; 3]; 3]) {
    let capped = (CAPPED_LOSS, [[0.0; 3]; 3]);
    let Some((depth, normal)) = depth_normal(ray, tri) else {
        return capped;
    };
    let gap = depth - target.depth as f64;
    if gap.is_nan() || gap.abs() > MAX_DEPTH_GAP {
        return capped;
    }
    let dn = sub(normal, target.normal.map(f64::from));
    let loss = gap * gap + dot(dn, dn);
    let e1 = sub(tri[1], tri[0]);
    let e2 = sub(tri[2], tri[0]);
    let n = cross(e1, e2);
    let len = norm(n);
    // Depth: ∂t/∂vᵢ = bᵢ·n/(n·d), the barycentric coordinates of the hit point.
    let x = add(ray.origin, scale(ray.dir, depth));
    let r = sub(x, tri[0]);
    let nn = dot(n, n);
    let b1 = dot(cross(r, e2), n) / nn;
    let b2 = dot(cross(e1, r), n) / nn;
    let b = [1.0 - b1 - b2, b1, b2];
    let dt = scale(n, 2.0 * gap / dot(n, ray.dir));
    // Normal: the gradient on n of ‖N − I_N‖², with N = normal = s·n/‖n‖.
    let g = scale(dn, 2.0);
    let gn = scale(sub(g, scale(normal, dot(normal, g))), 1.0 / len);
    // `normal` already carries s; (I − N̂N̂ᵀ) is the same for ±N̂, and ∂N/∂n = s·P/‖n‖.
    let s = dot(normal, n).signum();
    let gn = scale(gn, s);
    let g1 = cross(e2, gn);
    let g2 = cross(gn, e1);
    let g0 = scale(add(g1, g2), -1.0);
    let grad = [
        add(scale(dt, b[0]), g0),
        add(scale(dt, b[1]), g1),
        add(scale(dt, b[2]), g2),
    ];
    (loss, grad)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator for test values.
    fn values(seed: u64, n: usize) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
            })
            .collect()
    }

    #[test]
    fn the_gradient_agrees_with_finite_differences() {
        for seed in 0..20u64 {
            let v = values(seed, 9);
            // A triangle around the z axis, tilted, a ray straight down into it.
            let tri = [
                [-1.0 + 0.3 * v[0], -1.0 + 0.3 * v[1], 0.2 * v[2]],
                [1.2 + 0.3 * v[3], -0.8, 0.3 * v[4]],
                [0.1 * v[5], 1.1 + 0.2 * v[6], -0.2],
            ];
            let ray = PixelRay {
                origin: [0.05 * v[7], 0.05 * v[8], 10.0],
                dir: [0.0, 0.0, -1.0],
            };
            let tn = [0.1 * v[0], -0.2 * v[1], 1.0];
            let l = norm(tn);
            let target = Target {
                depth: (10.0 + 0.3 * v[2]) as f32,
                normal: tn.map(|c| (c / l) as f32),
            };
            let (loss, grad) = pixel_loss(&ray, &tri, &target);
            assert!(loss < CAPPED_LOSS && grad != [[0.0; 3]; 3]);
            let h = 1e-6;
            for i in 0..3 {
                for a in 0..3 {
                    let mut plus = tri;
                    plus[i][a] += h;
                    let mut minus = tri;
                    minus[i][a] -= h;
                    let fd = (pixel_loss(&ray, &plus, &target).0
                        - pixel_loss(&ray, &minus, &target).0)
                        / (2.0 * h);
                    let err = (fd - grad[i][a]).abs();
                    assert!(
                        err < 1e-6 * (1.0 + fd.abs()),
                        "seed {seed} corner {i} axis {a}: {fd} vs {}",
                        grad[i][a]
                    );
                }
            }
        }
    }

    #[test]
    fn a_pixel_that_sees_another_surface_is_capped_and_pulls_on_nothing() {
        let tri = [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]];
        let ray = PixelRay {
            origin: [0.0, 0.0, 5.0],
            dir: [0.0, 0.0, -1.0],
        };
        let far = Target {
            depth: 3.5,
            normal: [0.0, 0.0, 1.0],
        };
        assert_eq!(pixel_loss(&ray, &tri, &far), (CAPPED_LOSS, [[0.0; 3]; 3]));
        // The same plane within the gap: depth 5 against 5, normals equal, no loss.
        let same = Target {
            depth: 5.0,
            normal: [0.0, 0.0, 1.0],
        };
        let (loss, grad) = pixel_loss(&ray, &tri, &same);
        assert_eq!(loss, 0.0);
        assert!(grad.iter().flatten().all(|g| g.abs() < 1e-15));
        // Seen from below, the normal is turned towards the camera: still no loss against an
        // upward-looking target.
        let below = PixelRay {
            origin: [0.0, 0.0, -5.0],
            dir: [0.0, 0.0, 1.0],
        };
        let up = Target {
            depth: 5.0,
            normal: [0.0, 0.0, -1.0],
        };
        assert_eq!(pixel_loss(&below, &tri, &up).0, 0.0);
    }
}
