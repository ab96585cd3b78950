//! The cameras of the condition renders, by the rule of the peers' own render scripts, in the
//! frame those scripts render in: Blender's world (Z up), the asset scaled so that its longest
//! side is 1 and centred on the origin.
//!
//! TRELLIS (`dataset_toolkits/render_cond.py` `_render_cond`) and TRELLIS.2
//! (`data_toolkit/render_cond.py` `_render_cond`) share one rule: view `i` of `n` looks at the
//! origin from the direction of `sphere_hammersley_sequence(i, n, offset)`
//! (`dataset_toolkits/utils.py`: `u = i/n + offset₀/n`, `v` = the base-2 radical inverse of
//! `i` plus `offset₁`; `u` remapped so that a quarter of the views fall below the equator;
//! pitch `acos(1 − 2u) − π/2`, yaw `2πv`), with a random `offset` drawn once per asset; its
//! distance `r = 1/√k` with `k` uniform between `1/r_max²` and `1/r_min²`, where
//! `r = (√3/2) / sin(fov/2)` for the FoV range 10°–70°, so that the unit cube's bounding
//! sphere fills the frame at the view's FoV `2·asin((√3/2)/r)`. The camera
//! (`blender_script/render*.py` `init_camera`) tracks the origin with its −Z axis and keeps
//! its Y axis towards world +Z; `transform_matrix` is its camera-to-world matrix.
//! Our random draws are SplitMix64's ([`super::rng`]), seeded per item, not numpy's: the same
//! distributions, not the same numbers.

use super::rng::SplitMix64;
use glam::DVec3;
use sparc3d_raycast::Ray;

/// The narrowest and widest FoV of the TRELLIS rule, in degrees.
pub const FOV_RANGE_DEG: (f64, f64) = (10.0, 70.0);

/// The half-diagonal of the unit cube the asset is scaled into: the radius the views frame.
const FRAMED_RADIUS: f64 = 0.866_025_403_784_438_6; // √3 / 2

/// One view as the peers' scripts describe it: where the camera is and how wide it sees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Azimuth around world +Z, radians (0 = from +X).
    pub yaw: f64,
    /// Elevation above the XY plane, radians.
    pub pitch: f64,
    /// Distance from the origin.
    pub radius: f64,
    /// Horizontal (and vertical: the pictures are square) field of view, radians.
    pub fov: f64,
}

/// The base-2 radical inverse of `i` (its binary digits mirrored after the point).
fn radical_inverse_2(mut i: u64) -> f64 {
    let (mut value, mut scale) = (0.0, 0.5);
    while i > 0 {
        value += (i & 1) as f64 * scale;
        i >>= 1;
        scale *= 0.5;
    }
    value
}

/// `(yaw, pitch)` of view `i` of `n` on the Hammersley sphere shifted by `offset`, as
/// TRELLIS's `sphere_hammersley_sequence` places it.
pub fn hammersley_direction(i: u64, n: u64, offset: (f64, f64)) -> (f64, f64) {
    let n = n.max(1) as f64;
    let u = i as f64 / n + offset.0 / n;
    let v = radical_inverse_2(i) + offset.1;
    let u = if u < 0.25 {
        2.0 * u
    } else {
        2.0 / 3.0 * u + 1.0 / 3.0
    };
    let pitch = (1.0 - 2.0 * u).clamp(-1.0, 1.0).acos() - std::f64::consts::FRAC_PI_2;
    (v * std::f64::consts::TAU, pitch)
}

/// `n` views by the TRELLIS rule, their random draws from `rng`: the Hammersley offset first,
/// then one distance per view.
pub fn trellis_views(n: u32, rng: &mut SplitMix64) -> Vec<View> {
    let offset = (rng.uniform(), rng.uniform());
    let half = |deg: f64| (deg / 2.0).to_radians().sin();
    let radius_min = FRAMED_RADIUS / half(FOV_RANGE_DEG.1);
    let radius_max = FRAMED_RADIUS / half(FOV_RANGE_DEG.0);
    let (k_min, k_max) = (radius_max.powi(-2), radius_min.powi(-2));
    (0..n as u64)
        .map(|i| {
            let (yaw, pitch) = hammersley_direction(i, n as u64, offset);
            let k = k_min + (k_max - k_min) * rng.uniform();
            let radius = 1.0 / k.sqrt();
            let fov = 2.0 * (FRAMED_RADIUS / radius).min(1.0).asin();
            View {
                yaw,
                pitch,
                radius,
                fov,
            }
        })
        .collect()
}

/// A pinhole camera looking at the origin, in the frame of [`View`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PerspectiveCamera {
    /// Where it is.
    pub eye: DVec3,
    /// Its +X axis (right in the picture).
    pub right: DVec3,
    /// Its +Y axis (up in the picture).
    pub up: DVec3,
    /// Its +Z axis (it looks along −Z).
    pub back: DVec3,
    /// Field of view across the square picture, radians.
    pub fov: f64,
}

impl PerspectiveCamera {
    /// The camera of `view`: at its place, −Z at the origin, +Y towards world +Z (world +Y
    /// when it looks straight up or down), as Blender's TRACK_TO constraint sets it.
    pub fn of_view(view: &View) -> Self {
        let dir = DVec3::new(
            view.yaw.cos() * view.pitch.cos(),
            view.yaw.sin() * view.pitch.cos(),
            view.pitch.sin(),
        );
        let back = dir.normalize_or(DVec3::Z);
        let mut up = DVec3::Z - back * back.dot(DVec3::Z);
        if up.length_squared() < 1e-18 {
            up = DVec3::Y - back * back.dot(DVec3::Y);
        }
        let up = up.normalize();
        Self {
            eye: back * view.radius,
            right: up.cross(back),
            up,
            back,
            fov: view.fov,
        }
    }

    /// Its camera-to-world matrix, rows of a 4 × 4 (as `transform_matrix` in
    /// `transforms.json`): columns right, up, back, then the eye.
    pub fn transform_matrix(&self) -> [[f64; 4]; 4] {
        let (r, u, b, e) = (self.right, self.up, self.back, self.eye);
        [
            [r.x, u.x, b.x, e.x],
            [r.y, u.y, b.y, e.y],
            [r.z, u.z, b.z, e.z],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }

    /// The ray through point (`x`, `y`) of a `size × size` picture, in pixels from its
    /// top-left corner (a pixel's centre is at `+0.5`).
    pub fn ray(&self, x: f64, y: f64, size: u32) -> Ray {
        let s = size.max(1) as f64;
        let half = (self.fov / 2.0).tan();
        let u = (2.0 * x / s - 1.0) * half;
        let v = (1.0 - 2.0 * y / s) * half;
        let dir = (self.right * u + self.up * v - self.back).normalize();
        Ray::new_inf(self.eye.as_vec3a(), dir.as_vec3a())
    }

    /// The pixel (`x`, `y`, from the top-left corner) where the world point `p` is seen, if
    /// it is in front of the camera.
    pub fn project(&self, p: DVec3, size: u32) -> Option<(f64, f64)> {
        let d = p - self.eye;
        let depth = -d.dot(self.back);
        if depth <= 0.0 {
            return None;
        }
        let half = (self.fov / 2.0).tan();
        let u = d.dot(self.right) / depth / half;
        let v = d.dot(self.up) / depth / half;
        let s = size as f64;
        Some(((u + 1.0) * s / 2.0, (1.0 - v) * s / 2.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hammersley_views_follow_trellis_and_a_quarter_look_from_below() {
        // i = 0 with no offset: u = 0, straight below; the radical inverse of 1, 2, 3 in base 2.
        let (_, p) = hammersley_direction(0, 24, (0.0, 0.0));
        assert!((p + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert_eq!(radical_inverse_2(1), 0.5);
        assert_eq!(radical_inverse_2(6), 0.375);
        let mut rng = SplitMix64::new(3);
        let views = trellis_views(24, &mut rng);
        let below = views.iter().filter(|v| v.pitch < 0.0).count();
        assert_eq!(
            below, 6,
            "TRELLIS puts a quarter of the views below the equator"
        );
        for v in &views {
            let fov = v.fov.to_degrees();
            assert!((10.0 - 1e-9..=70.0 + 1e-9).contains(&fov), "{fov}");
            // The unit cube's bounding sphere touches the frame: sin(fov/2)·r = √3/2.
            assert!(((v.fov / 2.0).sin() * v.radius - FRAMED_RADIUS).abs() < 1e-9);
        }
        assert_eq!(trellis_views(24, &mut SplitMix64::new(3)), views);
    }

    #[test]
    fn the_camera_frame_is_blenders_track_to_and_projects_its_own_rays_back() {
        let view = View {
            yaw: 0.3,
            pitch: 0.4,
            radius: 2.0,
            fov: 0.7,
        };
        let cam = PerspectiveCamera::of_view(&view);
        for (a, b) in [
            (cam.right, cam.up),
            (cam.up, cam.back),
            (cam.right, cam.back),
        ] {
            assert!(a.dot(b).abs() < 1e-12);
        }
        assert!(
            (cam.right.cross(cam.up) - cam.back).length() < 1e-12,
            "right-handed"
        );
        assert!(cam.right.z.abs() < 1e-12, "no roll: right stays horizontal");
        assert!(cam.up.z > 0.0);
        let centre = cam.ray(64.0, 64.0, 128);
        assert!((centre.direction.as_dvec3() + cam.back).length() < 1e-6);
        let ray = cam.ray(10.5, 100.25, 128);
        let point = ray.origin.as_dvec3() + ray.direction.as_dvec3() * 1.7;
        let (x, y) = cam.project(point, 128).unwrap_or((f64::NAN, f64::NAN));
        assert!(
            (x - 10.5).abs() < 1e-3 && (y - 100.25).abs() < 1e-3,
            "{x} {y}"
        );
        let m = cam.transform_matrix();
        assert_eq!([m[0][3], m[1][3], m[2][3]], cam.eye.to_array());
        let straight_down = PerspectiveCamera::of_view(&View {
            pitch: -std::f64::consts::FRAC_PI_2,
            ..view
        });
        assert!(straight_down.up.is_finite() && straight_down.right.is_finite());
    }
}
