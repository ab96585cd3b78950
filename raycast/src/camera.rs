//! Orthographic cameras: where they look from and the ray through each pixel.

use glam::Vec3A;
use obvhs::ray::Ray;

/// An orthographic camera: parallel rays along `forward`, through a square window of half
/// side `half_extent` centred on `center`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Centre of the view window (a point the camera looks at).
    pub center: [f32; 3],
    /// Unit viewing direction (from the camera into the scene).
    pub forward: [f32; 3],
    /// Unit vector pointing right in the picture, orthogonal to `forward`.
    pub right: [f32; 3],
    /// Unit vector pointing up in the picture, orthogonal to `forward` and `right`.
    pub up: [f32; 3],
    /// Half the side of the square window, in scene units (> 0).
    pub half_extent: f32,
    /// How far behind `center` rays start, in scene units: beyond the scene's bounds.
    pub distance: f32,
}

impl Camera {
    /// A camera looking at `center` from azimuth `azimuth_deg` (around +Y, 0 = from +Z) and
    /// elevation `elevation_deg` (above the XZ plane), with a window of half side
    /// `half_extent`. +Y is up in the picture.
    pub fn orbit(center: [f32; 3], half_extent: f32, azimuth_deg: f32, elevation_deg: f32) -> Self {
        let (az, el) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
        // Direction from the centre towards the camera.
        let eye = Vec3A::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos());
        Self::looking(center, (-eye).into(), half_extent)
    }

    /// A camera looking at `center` along `forward` (any non-zero vector), with a window of
    /// half side `half_extent`; +Y is up in the picture unless `forward` is vertical (then
    /// +X is right).
    pub fn looking(center: [f32; 3], forward: [f32; 3], half_extent: f32) -> Self {
        let forward = Vec3A::from(forward).normalize_or(Vec3A::NEG_Z);
        let mut right = forward.cross(Vec3A::Y);
        if right.length_squared() < 1e-12 {
            right = Vec3A::X;
        }
        let right = right.normalize();
        let up = right.cross(forward).normalize();
        Self {
            center,
            forward: forward.into(),
            right: right.into(),
            up: up.into(),
            half_extent: half_extent.max(f32::MIN_POSITIVE),
            distance: 4.0 * half_extent.max(1e-6),
        }
    }

    /// The ray through the centre of pixel (`x`, `y`) of a `size × size` picture (row `y`
    /// counted from the top); its direction is `forward`, a unit vector.
    pub fn ray(&self, x: u32, y: u32, size: u32) -> Ray {
        let s = size.max(1) as f32;
        let u = ((x as f32 + 0.5) / s * 2.0 - 1.0) * self.half_extent;
        let v = (1.0 - (y as f32 + 0.5) / s * 2.0) * self.half_extent;
        let forward = Vec3A::from(self.forward);
        let origin =
            Vec3A::from(self.center) + Vec3A::from(self.right) * u + Vec3A::from(self.up) * v
                - forward * self.distance;
        Ray::new_inf(origin, forward)
    }
}

/// The centre and the radius of the bounding sphere of the box `bounds`.
fn bounding_sphere(bounds: ([f64; 3], [f64; 3])) -> ([f32; 3], f64) {
    let (lo, hi) = bounds;
    let center = std::array::from_fn(|a| ((lo[a] + hi[a]) * 0.5) as f32);
    let radius =
        ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt() * 0.5;
    (center, radius)
}

/// `views` cameras evenly spaced in azimuth (the first at 30°) at `elevation_deg`, framing the
/// box `bounds` (its bounding sphere fills the picture with a 5% margin).
pub fn orbit_cameras(bounds: ([f64; 3], [f64; 3]), views: u32, elevation_deg: f32) -> Vec<Camera> {
    let (center, radius) = bounding_sphere(bounds);
    let half_extent = (radius * 1.05).max(1e-6) as f32;
    let n = views.max(1);
    (0..n)
        .map(|i| {
            let azimuth = 30.0 + 360.0 * i as f32 / n as f32;
            Camera::orbit(center, half_extent, azimuth, elevation_deg)
        })
        .collect()
}

/// `n` unit directions spread evenly over the sphere: the Fibonacci lattice (point `i` at
/// height `1 − (2i + 1)/n`, turned by the golden angle from the one before), which has no
/// two points close together for any `n` and puts none on a coordinate axis.
pub fn sphere_directions(n: u32) -> Vec<[f64; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let a = golden * i as f64;
            [r * a.cos(), z, r * a.sin()]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_directions_are_unit_and_balanced() {
        for n in [1, 2, 7, 16] {
            let d = sphere_directions(n);
            assert_eq!(d.len(), n as usize);
            let mut sum = [0.0; 3];
            for v in &d {
                let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                assert!((len - 1.0).abs() < 1e-12);
                sum = std::array::from_fn(|a| sum[a] + v[a]);
            }
            // Spread evenly: the mean direction is short for more than a couple of views.
            if n >= 7 {
                assert!(sum.iter().all(|s| (s / n as f64).abs() < 0.15), "{sum:?}");
            }
        }
    }

    #[test]
    fn a_pixel_ray_starts_behind_the_window_and_runs_along_forward() {
        let c = Camera::looking([1.0, 2.0, 3.0], [0.0, 0.0, -2.0], 4.0);
        let ray = c.ray(1, 1, 2);
        // Pixel (1, 1) of 2×2 is right of and below the centre by half a half-extent.
        assert_eq!(ray.direction, Vec3A::new(0.0, 0.0, -1.0));
        let o = ray.origin;
        assert!((o.x - 3.0).abs() < 1e-6 && (o.y - 0.0).abs() < 1e-6 && o.z > 3.0);
    }
}
