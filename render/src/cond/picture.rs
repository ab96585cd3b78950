//! One condition view traced: a ray per pixel, then a 4 × 4 grid of rays in each pixel at an
//! edge (a neighbour that sees the background where it sees the asset, or a surface turned
//! another way), so that silhouettes and creases are antialiased at little more than one ray
//! a pixel. Alpha is the share of a pixel's rays that hit the asset (times the material's
//! alpha); colours are straight (not premultiplied), as Blender writes RGBA PNGs.

use super::cameras::PerspectiveCamera;
use super::lights::Lights;
use super::passes::{CentreSample, Pass, PassSet};
use super::Surface;
use glam::Vec3A;
use rayon::prelude::*;
use sparcubes::colour::{linear_to_srgb, to_byte};

/// Rays per side of the grid cast in a pixel at an edge.
const EDGE_GRID: u32 = 4;

/// Normals of two neighbours closer than this (cosine) are one smooth surface.
const CREASE_COS: f32 = 0.97;

/// An 8-bit RGBA picture, rows top to bottom, straight alpha.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RgbaImage {
    /// Width and height in pixels.
    pub size: u32,
    /// `size × size × 4` bytes, row-major, RGBA.
    pub rgba: Vec<u8>,
}

impl RgbaImage {
    /// The picture as a PNG file (8-bit RGBA).
    pub fn encode_png(&self) -> std::io::Result<Vec<u8>> {
        crate::encode_png(self.size, self.size, png::ColorType::Rgba, &self.rgba)
    }

    /// The alpha of pixel (`x`, `y`).
    pub fn alpha(&self, x: u32, y: u32) -> u8 {
        self.rgba[(y as usize * self.size as usize + x as usize) * 4 + 3]
    }
}

/// What one ray saw: premultiplied linear RGBA, lit and unlit, the surface's normal (zero on
/// a miss) and its distance from the camera's plane (infinite on a miss).
#[derive(Clone, Copy)]
struct Seen {
    rgba: [f32; 4],
    albedo: [f32; 4],
    normal: Vec3A,
    depth: f32,
    hit: bool,
}

impl Default for Seen {
    fn default() -> Self {
        Self {
            rgba: [0.0; 4],
            albedo: [0.0; 4],
            normal: Vec3A::ZERO,
            depth: f32::INFINITY,
            hit: false,
        }
    }
}

/// What a view's passes need beyond its picture ([`super::passes`]): the centre rays'
/// normals and depths when a normal or depth pass is asked for, the base colours as 8-bit
/// RGBA when an albedo pass is; empty otherwise.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PassData {
    /// One per pixel, row-major.
    pub centres: Vec<CentreSample>,
    /// `size × size × 4` bytes, straight sRGB and the view's alpha.
    pub albedo: Vec<u8>,
}

/// Traces the view of `camera` (`size` pixels a side) of `surface` lit by `lights`; rows
/// in parallel, every pixel depending only on its own rays.
pub fn trace(
    surface: &Surface<'_>,
    camera: &PerspectiveCamera,
    lights: &Lights,
    size: u32,
) -> RgbaImage {
    trace_with(surface, camera, lights, size, PassSet::NONE).0
}

/// [`trace`], with what `passes` need of the same rays.
pub fn trace_with(
    surface: &Surface<'_>,
    camera: &PerspectiveCamera,
    lights: &Lights,
    size: u32,
    passes: PassSet,
) -> (RgbaImage, PassData) {
    let n = size as usize;
    let mut centres = vec![Seen::default(); n * n];
    centres
        .par_chunks_mut(n.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, seen) in row.iter_mut().enumerate() {
                *seen = look(
                    surface,
                    camera,
                    lights,
                    x as f64 + 0.5,
                    y as f64 + 0.5,
                    size,
                );
            }
        });
    let with_albedo = passes.contains(Pass::Albedo);
    let mut rgba = vec![0u8; n * n * 4];
    let mut albedo = vec![0u8; if with_albedo { n * n * 4 } else { 0 }];
    let rows = rgba.par_chunks_mut((n * 4).max(1));
    let albedo_rows = albedo.par_chunks_mut((n * 4).max(1));
    let fill = |y: usize, row: &mut [u8], albedo_row: Option<&mut [u8]>| {
        let mut albedo_row = albedo_row;
        for x in 0..n {
            let [lit, unlit] = match at_edge(&centres, n, x, y) {
                true => grid(surface, camera, lights, x, y, size),
                false => [centres[y * n + x].rgba, centres[y * n + x].albedo],
            };
            row[x * 4..x * 4 + 4].copy_from_slice(&to_bytes(lit));
            if let Some(a) = albedo_row.as_deref_mut() {
                a[x * 4..x * 4 + 4].copy_from_slice(&to_bytes(unlit));
            }
        }
    };
    match with_albedo {
        true => rows
            .zip(albedo_rows)
            .enumerate()
            .for_each(|(y, (row, a))| fill(y, row, Some(a))),
        false => rows.enumerate().for_each(|(y, row)| fill(y, row, None)),
    }
    let data = PassData {
        centres: match passes.contains(Pass::Normal) || passes.contains(Pass::Depth) {
            true => centres.iter().map(centre_sample).collect(),
            false => Vec::new(),
        },
        albedo,
    };
    (RgbaImage { size, rgba }, data)
}

/// The normal and depth a centre ray saw.
fn centre_sample(seen: &Seen) -> CentreSample {
    CentreSample {
        normal: seen.normal.to_array(),
        depth: seen.depth,
    }
}

/// Whether pixel (`x`, `y`) differs from a neighbour in what its centre ray saw.
fn at_edge(centres: &[Seen], n: usize, x: usize, y: usize) -> bool {
    let me = centres[y * n + x];
    let (x0, x1) = (x.saturating_sub(1), (x + 1).min(n - 1));
    let (y0, y1) = (y.saturating_sub(1), (y + 1).min(n - 1));
    (y0..=y1).any(|ny| {
        (x0..=x1).any(|nx| {
            let other = centres[ny * n + nx];
            other.hit != me.hit || (me.hit && other.normal.dot(me.normal) < CREASE_COS)
        })
    })
}

/// The means of an `EDGE_GRID²` grid of rays in pixel (`x`, `y`), lit and unlit.
fn grid(
    surface: &Surface<'_>,
    camera: &PerspectiveCamera,
    lights: &Lights,
    x: usize,
    y: usize,
    size: u32,
) -> [[f32; 4]; 2] {
    let mut sum = [[0.0f32; 4]; 2];
    let step = 1.0 / EDGE_GRID as f64;
    for j in 0..EDGE_GRID {
        for i in 0..EDGE_GRID {
            let sx = x as f64 + (i as f64 + 0.5) * step;
            let sy = y as f64 + (j as f64 + 0.5) * step;
            let seen = look(surface, camera, lights, sx, sy, size);
            for (sums, values) in sum.iter_mut().zip([seen.rgba, seen.albedo]) {
                for (s, v) in sums.iter_mut().zip(values) {
                    *s += v;
                }
            }
        }
    }
    sum.map(|s| s.map(|v| v / (EDGE_GRID * EDGE_GRID) as f32))
}

/// What the ray through picture point (`sx`, `sy`) sees.
fn look(
    surface: &Surface<'_>,
    camera: &PerspectiveCamera,
    lights: &Lights,
    sx: f64,
    sy: f64,
    size: u32,
) -> Seen {
    let ray = camera.ray(sx, sy, size);
    let Some(hit) = surface.scene.cast(ray) else {
        return Seen::default();
    };
    let t = hit.triangle as usize;
    let point = ray.origin + ray.direction * hit.t;
    let [v0, v1, v2] = surface.corners[t];
    let mut normal = (v1 - v0).cross(v2 - v0).normalize_or_zero();
    if normal.dot(ray.direction) > 0.0 {
        normal = -normal;
    }
    let footprint = pixel_footprint(camera, hit.t as f64, size) / surface.scale;
    let [r, g, b, alpha] = surface.albedo(t, point, footprint);
    let light = lights.at(normal, point.as_dvec3());
    let a = alpha.clamp(0.0, 1.0);
    let depth = -(point - camera.eye.as_vec3a()).dot(camera.back.as_vec3a());
    Seen {
        rgba: [r * light * a, g * light * a, b * light * a, a],
        albedo: [r * a, g * a, b * a, a],
        normal,
        depth,
        hit: true,
    }
}

/// The side of one pixel, in the normalized frame, at distance `t` along a ray.
fn pixel_footprint(camera: &PerspectiveCamera, t: f64, size: u32) -> f64 {
    2.0 * t * (camera.fov / 2.0).tan() / size.max(1) as f64
}

/// Straight sRGB bytes of premultiplied linear RGBA.
fn to_bytes(rgba: [f32; 4]) -> [u8; 4] {
    let a = rgba[3];
    if a <= 0.0 {
        return [0; 4];
    }
    let c = |v: f32| to_byte(linear_to_srgb((v / a).clamp(0.0, 1.0)));
    [c(rgba[0]), c(rgba[1]), c(rgba[2]), to_byte(a)]
}
