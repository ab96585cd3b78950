//! Preview rendering: ray-cast shaded pictures of meshes, so a broken conversion is seen at a
//! glance.
//!
//! A [`Scene`] is a BVH (obvhs) over one mesh's triangles. [`orbit_cameras`] places
//! orthographic cameras around a bounding box at a fixed elevation; [`render`] casts one ray per
//! pixel and shades the nearest hit with a headlight (Lambert plus a little ambient). Front
//! faces (counter-clockwise seen from the camera) are grey-blue, back faces red: back faces in
//! sight mean an open or inverted surface. The background is white.
//!
//! Rows are rendered in parallel (rayon); every pixel depends only on its own ray, so the bytes
//! are the same for any number of threads. [`compare`] lays out a source row above an output
//! row, one tile per view, [`label::draw`] burns a caption into it, and [`Image::encode_png`]
//! writes the picture as PNG.
#![deny(missing_docs)]

pub mod label;

use glam::Vec3A;
use obvhs::bvh2::builder::build_bvh2_from_tris;
use obvhs::bvh2::Bvh2;
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;
use rayon::prelude::*;
use sparcubes::TriMesh;
use std::time::Duration;

/// Background colour (white).
pub const BACKGROUND: [u8; 3] = [255, 255, 255];
/// Base colour of front faces (grey-blue).
pub const FRONT: [u8; 3] = [150, 175, 215];
/// Base colour of back faces (red): visible back faces mean an open or inverted surface.
pub const BACK: [u8; 3] = [225, 70, 60];
/// Colour of the lines between tiles in [`compare`].
pub const SEPARATOR: [u8; 3] = [200, 200, 200];
/// Share of the base colour lit regardless of the angle to the light.
const AMBIENT: f32 = 0.25;

/// An 8-bit RGB picture, rows top to bottom.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width × height × 3` bytes, row-major, RGB.
    pub rgb: Vec<u8>,
}

impl Image {
    /// A picture filled with one colour.
    pub fn filled(width: u32, height: u32, colour: [u8; 3]) -> Self {
        let n = width as usize * height as usize;
        let mut rgb = Vec::with_capacity(n * 3);
        for _ in 0..n {
            rgb.extend_from_slice(&colour);
        }
        Self { width, height, rgb }
    }

    /// The colour of pixel (`x`, `y`); `None` outside the picture.
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = (y as usize * self.width as usize + x as usize) * 3;
        Some([self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]])
    }

    /// Copies `tile` with its top-left corner at (`x`, `y`), clipping what falls outside.
    pub fn blit(&mut self, tile: &Image, x: u32, y: u32) {
        for ty in 0..tile.height {
            let dy = y + ty;
            if dy >= self.height || x >= self.width {
                break;
            }
            let w = tile.width.min(self.width - x) as usize;
            let src = ty as usize * tile.width as usize * 3;
            let dst = (dy as usize * self.width as usize + x as usize) * 3;
            self.rgb[dst..dst + w * 3].copy_from_slice(&tile.rgb[src..src + w * 3]);
        }
    }

    /// Paints the rectangle `[x0, x1) × [y0, y1)` (clipped) with one colour.
    pub fn fill_rect(&mut self, x0: u32, y0: u32, x1: u32, y1: u32, colour: [u8; 3]) {
        for y in y0..y1.min(self.height) {
            for x in x0..x1.min(self.width) {
                let i = (y as usize * self.width as usize + x as usize) * 3;
                self.rgb[i..i + 3].copy_from_slice(&colour);
            }
        }
    }

    /// The picture as a PNG file (8-bit RGB, default compression).
    pub fn encode_png(&self) -> std::io::Result<Vec<u8>> {
        let mut bytes = Vec::new();
        {
            let mut encoder = png::Encoder::new(&mut bytes, self.width, self.height);
            encoder.set_color(png::ColorType::Rgb);
            encoder.set_depth(png::BitDepth::Eight);
            let mut writer = encoder.write_header().map_err(std::io::Error::other)?;
            writer
                .write_image_data(&self.rgb)
                .map_err(std::io::Error::other)?;
            writer.finish().map_err(std::io::Error::other)?;
        }
        Ok(bytes)
    }
}

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
        let forward = -eye;
        let world_up = Vec3A::Y;
        let mut right = forward.cross(world_up);
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

    /// The ray through the centre of pixel (`x`, `y`) of a `size × size` picture.
    fn ray(&self, x: u32, y: u32, size: u32) -> Ray {
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

/// `views` cameras evenly spaced in azimuth (the first at 30°) at `elevation_deg`, framing the
/// box `bounds` (its bounding sphere fills the picture with a 5% margin).
pub fn orbit_cameras(bounds: ([f64; 3], [f64; 3]), views: u32, elevation_deg: f32) -> Vec<Camera> {
    let (lo, hi) = bounds;
    let center = [
        ((lo[0] + hi[0]) * 0.5) as f32,
        ((lo[1] + hi[1]) * 0.5) as f32,
        ((lo[2] + hi[2]) * 0.5) as f32,
    ];
    let radius =
        ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt() * 0.5;
    let half_extent = (radius * 1.05).max(1e-6) as f32;
    let n = views.max(1);
    (0..n)
        .map(|i| {
            let azimuth = 30.0 + 360.0 * i as f32 / n as f32;
            Camera::orbit(center, half_extent, azimuth, elevation_deg)
        })
        .collect()
}

/// A mesh ready for ray casting: its triangles and a BVH over them.
pub struct Scene {
    /// Triangles, indexed through `bvh.primitive_indices`.
    triangles: Vec<Triangle>,
    /// The BVH; `None` for a mesh without triangles.
    bvh: Option<Bvh2>,
}

impl Scene {
    /// Builds the BVH over `mesh`'s triangles (single-threaded, deterministic). Triangles with
    /// an index out of range are skipped.
    pub fn new(mesh: &TriMesh) -> Self {
        let p = &mesh.positions;
        let triangles: Vec<Triangle> = mesh
            .triangles
            .iter()
            .filter(|t| t.iter().all(|&i| (i as usize) < p.len()))
            .map(|t| Triangle {
                v0: Vec3A::from(p[t[0] as usize]),
                v1: Vec3A::from(p[t[1] as usize]),
                v2: Vec3A::from(p[t[2] as usize]),
            })
            .collect();
        let bvh = if triangles.is_empty() {
            None
        } else {
            Some(build_bvh2_from_tris(
                &triangles,
                BvhBuildParams::medium_build(),
                &mut Duration::default(),
            ))
        };
        Self { triangles, bvh }
    }

    /// The colour seen along `ray`: background, or the shaded nearest triangle.
    fn shade(&self, ray: Ray) -> [u8; 3] {
        let Some(bvh) = &self.bvh else {
            return BACKGROUND;
        };
        let mut hit = RayHit::none();
        let found = bvh.ray_traverse(ray, &mut hit, |ray, id| {
            intersect(&self.triangles[bvh.primitive_indices[id] as usize], ray)
        });
        if !found {
            return BACKGROUND;
        }
        let tri = &self.triangles[bvh.primitive_indices[hit.primitive_id as usize] as usize];
        let normal = (tri.v1 - tri.v0).cross(tri.v2 - tri.v0).normalize_or_zero();
        let facing = normal.dot(ray.direction);
        let base = if facing <= 0.0 { FRONT } else { BACK };
        let light = AMBIENT + (1.0 - AMBIENT) * facing.abs().min(1.0);
        base.map(|c| (c as f32 * light).round().clamp(0.0, 255.0) as u8)
    }
}

/// Distance along `ray` to `tri` (Möller–Trumbore), or infinity on a miss. Barycentric
/// coordinates down to `-1e-6` count as inside, so a ray through an edge shared by two
/// triangles hits one of them (no speckles along diagonals).
fn intersect(tri: &Triangle, ray: &Ray) -> f32 {
    const EPS: f32 = 1e-6;
    let e1 = tri.v1 - tri.v0;
    let e2 = tri.v2 - tri.v0;
    let p = ray.direction.cross(e2);
    let det = e1.dot(p);
    if det.abs() < f32::MIN_POSITIVE {
        return f32::INFINITY;
    }
    let inv = 1.0 / det;
    let s = ray.origin - tri.v0;
    let u = s.dot(p) * inv;
    let q = s.cross(e1);
    let v = ray.direction.dot(q) * inv;
    if u < -EPS || v < -EPS || u + v > 1.0 + EPS {
        return f32::INFINITY;
    }
    let t = e2.dot(q) * inv;
    if t >= ray.tmin && t <= ray.tmax {
        t
    } else {
        f32::INFINITY
    }
}

/// Renders `scene` through `camera` into a `size × size` picture, rows in parallel.
pub fn render(scene: &Scene, camera: &Camera, size: u32) -> Image {
    let width = size as usize;
    let mut rgb = vec![0u8; width * width * 3];
    if width > 0 {
        rgb.par_chunks_mut(width * 3)
            .enumerate()
            .for_each(|(y, row)| {
                for x in 0..width {
                    let c = scene.shade(camera.ray(x as u32, y as u32, size));
                    row[x * 3..x * 3 + 3].copy_from_slice(&c);
                }
            });
    }
    Image {
        width: size,
        height: size,
        rgb,
    }
}

/// Options of [`compare`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompareOptions {
    /// Views per mesh, evenly spaced in azimuth (at least 1).
    pub views: u32,
    /// Side of one tile in pixels.
    pub tile: u32,
    /// Camera elevation in degrees.
    pub elevation_deg: f32,
}

impl Default for CompareOptions {
    fn default() -> Self {
        Self {
            views: 4,
            tile: 256,
            elevation_deg: 30.0,
        }
    }
}

/// Renders each mesh of `rows` (e.g. source, then output) from the same cameras, framing the
/// union of their bounds: one row of `views` tiles per mesh, separated by 2-pixel grey lines.
pub fn compare(rows: &[&TriMesh], options: &CompareOptions) -> Image {
    let views = options.views.max(1);
    let tile = options.tile;
    let gap = 2;
    let bounds = rows
        .iter()
        .filter_map(|m| m.bounds())
        .reduce(|a, b| {
            (
                [a.0[0].min(b.0[0]), a.0[1].min(b.0[1]), a.0[2].min(b.0[2])],
                [a.1[0].max(b.1[0]), a.1[1].max(b.1[1]), a.1[2].max(b.1[2])],
            )
        })
        .unwrap_or(([-1.0; 3], [1.0; 3]));
    let cameras = orbit_cameras(bounds, views, options.elevation_deg);
    let n_rows = rows.len().max(1) as u32;
    let width = views * tile + (views - 1) * gap;
    let height = n_rows * tile + (n_rows - 1) * gap;
    let mut image = Image::filled(width, height, SEPARATOR);
    for (r, mesh) in rows.iter().enumerate() {
        let scene = Scene::new(mesh);
        for (v, camera) in cameras.iter().enumerate() {
            let picture = render(&scene, camera, tile);
            image.blit(&picture, v as u32 * (tile + gap), r as u32 * (tile + gap));
        }
    }
    image
}
