//! Preview rendering: ray-cast shaded pictures of meshes, so a broken conversion is seen at a
//! glance.
//!
//! A [`Scene`] is a BVH over one mesh's triangles (`sparc3d-raycast`, which also casts the rays
//! of the rendering-based refinement). [`orbit_cameras`] places
//! orthographic cameras around a bounding box at a fixed elevation; [`render`] casts one ray per
//! pixel and shades the nearest hit with a headlight (Lambert plus a little ambient). Front
//! faces (counter-clockwise seen from the camera) are grey-blue, back faces red: back faces in
//! sight mean an open or inverted surface. The background is white.
//!
//! A mesh drawn with a [`paint::Paint`] ([`render_painted`], [`compare_painted`]) has its front
//! faces in the colour the paint gives the point hit (its vertex colours, or its materials and
//! textures), lit the same way; back faces stay red. Without a paint the pixels are exactly the
//! grey-blue pictures above.
//!
//! Rows are rendered in parallel (rayon); every pixel depends only on its own ray, so the bytes
//! are the same for any number of threads. [`compare`] lays out a source row above an output
//! row, one tile per view, [`label::draw`] burns a caption into it, and [`Image::encode_png`]
//! writes the picture as PNG.
#![deny(missing_docs)]

pub mod cond;
pub mod label;
pub mod paint;

use glam::Vec3A;
use paint::Paint;
use rayon::prelude::*;
pub use sparc3d_raycast::{orbit_cameras, Camera};
use sparc3d_raycast::{Ray, Scene as RayScene};
use sparcubes::TriMesh;

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
        encode_png(self.width, self.height, png::ColorType::Rgb, &self.rgb)
    }
}

/// `data` (8-bit samples of `colour`, rows top to bottom) as a PNG file.
pub(crate) fn encode_png(
    width: u32,
    height: u32,
    colour: png::ColorType,
    data: &[u8],
) -> std::io::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut bytes, width, height);
        encoder.set_color(colour);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(std::io::Error::other)?;
        writer
            .write_image_data(data)
            .map_err(std::io::Error::other)?;
        writer.finish().map_err(std::io::Error::other)?;
    }
    Ok(bytes)
}

/// `data` (16-bit samples of `colour`, rows top to bottom) as a PNG file (big-endian
/// samples, as PNG stores them).
pub(crate) fn encode_png16(
    width: u32,
    height: u32,
    colour: png::ColorType,
    data: &[u16],
) -> std::io::Result<Vec<u8>> {
    let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_be_bytes()).collect();
    let mut out = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut out, width, height);
        encoder.set_color(colour);
        encoder.set_depth(png::BitDepth::Sixteen);
        let mut writer = encoder.write_header().map_err(std::io::Error::other)?;
        writer
            .write_image_data(&bytes)
            .map_err(std::io::Error::other)?;
        writer.finish().map_err(std::io::Error::other)?;
    }
    Ok(out)
}

/// A mesh ready for ray casting ([`sparc3d_raycast::Scene`]) with its corners for shading.
pub struct Scene {
    /// The BVH over the mesh's triangles.
    scene: RayScene,
    /// Corners of each triangle of the mesh (zeros for one with an index out of range,
    /// which the BVH skips).
    corners: Vec<[Vec3A; 3]>,
}

impl Scene {
    /// Builds the BVH over `mesh`'s triangles (single-threaded, deterministic). Triangles with
    /// an index out of range are skipped.
    pub fn new(mesh: &TriMesh) -> Self {
        let p = &mesh.positions;
        let corners = mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| p.get(i as usize).map_or(Vec3A::ZERO, |&c| Vec3A::from(c))))
            .collect();
        Self {
            scene: RayScene::new(p, &mesh.triangles),
            corners,
        }
    }

    /// The colour seen along `ray`: background, or the shaded nearest triangle, its front
    /// in `paint`'s colour when given.
    fn shade(&self, ray: Ray, paint: Option<&dyn Paint>) -> [u8; 3] {
        let Some(hit) = self.scene.cast(ray) else {
            return BACKGROUND;
        };
        let [v0, v1, v2] = self.corners[hit.triangle as usize];
        let normal = (v1 - v0).cross(v2 - v0).normalize_or_zero();
        let facing = normal.dot(ray.direction);
        let base = match (facing <= 0.0, paint) {
            (false, _) => BACK,
            (true, None) => FRONT,
            (true, Some(p)) => {
                let point = ray.origin + ray.direction * hit.t;
                p.colour(hit.triangle as usize, barycentric(point, [v0, v1, v2]))
            }
        };
        let light = AMBIENT + (1.0 - AMBIENT) * facing.abs().min(1.0);
        base.map(|c| (c as f32 * light).round().clamp(0.0, 255.0) as u8)
    }
}

/// Barycentric coordinates of `p` (on the triangle's plane) in triangle `t`, each clamped to
/// [0, 1]; the centroid's for a degenerate triangle.
pub(crate) fn barycentric(p: Vec3A, t: [Vec3A; 3]) -> [f32; 3] {
    let (e0, e1, ep) = (t[1] - t[0], t[2] - t[0], p - t[0]);
    let (d00, d01, d11) = (e0.dot(e0), e0.dot(e1), e1.dot(e1));
    let (d20, d21) = (ep.dot(e0), ep.dot(e1));
    let den = d00 * d11 - d01 * d01;
    if !den.is_normal() {
        return [1.0 / 3.0; 3];
    }
    let v = ((d11 * d20 - d01 * d21) / den).clamp(0.0, 1.0);
    let w = ((d00 * d21 - d01 * d20) / den).clamp(0.0, 1.0 - v);
    [1.0 - v - w, v, w]
}

/// Renders `scene` through `camera` into a `size × size` picture, rows in parallel.
pub fn render(scene: &Scene, camera: &Camera, size: u32) -> Image {
    render_painted(scene, None, camera, size)
}

/// [`render`] with the front faces in `paint`'s colours (the plain picture without one).
pub fn render_painted(
    scene: &Scene,
    paint: Option<&dyn Paint>,
    camera: &Camera,
    size: u32,
) -> Image {
    let width = size as usize;
    let mut rgb = vec![0u8; width * width * 3];
    if width > 0 {
        rgb.par_chunks_mut(width * 3)
            .enumerate()
            .for_each(|(y, row)| {
                for x in 0..width {
                    let c = scene.shade(camera.ray(x as u32, y as u32, size), paint);
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

/// One row of [`compare_painted`]: a mesh and, when drawn in colour, its paint.
#[derive(Clone, Copy)]
pub struct Drawn<'a> {
    /// The mesh.
    pub mesh: &'a TriMesh,
    /// Its colours (the plain grey-blue without).
    pub paint: Option<&'a dyn Paint>,
}

/// Renders each mesh of `rows` (e.g. source, then output) from the same cameras, framing the
/// union of their bounds: one row of `views` tiles per mesh, separated by 2-pixel grey lines.
pub fn compare(rows: &[&TriMesh], options: &CompareOptions) -> Image {
    let drawn: Vec<Drawn> = rows
        .iter()
        .map(|&mesh| Drawn { mesh, paint: None })
        .collect();
    compare_painted(&drawn, options)
}

/// The side of one pixel, in scene units, of the pictures [`compare`] draws of meshes within
/// `bounds` (what a paint filters its textures over).
pub fn pixel_size(bounds: ([f64; 3], [f64; 3]), options: &CompareOptions) -> f64 {
    let camera = orbit_cameras(bounds, 1, options.elevation_deg);
    camera.first().map_or(0.0, |c| {
        2.0 * c.half_extent as f64 / options.tile.max(1) as f64
    })
}

/// The union of the bounds of `meshes`, the box [-1, 1]³ when none has any.
pub fn union_bounds<'a>(meshes: impl Iterator<Item = &'a TriMesh>) -> ([f64; 3], [f64; 3]) {
    meshes
        .filter_map(|m| m.bounds())
        .reduce(|a, b| {
            (
                [a.0[0].min(b.0[0]), a.0[1].min(b.0[1]), a.0[2].min(b.0[2])],
                [a.1[0].max(b.1[0]), a.1[1].max(b.1[1]), a.1[2].max(b.1[2])],
            )
        })
        .unwrap_or(([-1.0; 3], [1.0; 3]))
}

/// [`compare`] with each row painted as its [`Drawn`] says.
pub fn compare_painted(rows: &[Drawn], options: &CompareOptions) -> Image {
    let views = options.views.max(1);
    let tile = options.tile;
    let gap = 2;
    let bounds = union_bounds(rows.iter().map(|d| d.mesh));
    let cameras = orbit_cameras(bounds, views, options.elevation_deg);
    let n_rows = rows.len().max(1) as u32;
    let width = views * tile + (views - 1) * gap;
    let height = n_rows * tile + (n_rows - 1) * gap;
    let mut image = Image::filled(width, height, SEPARATOR);
    for (r, drawn) in rows.iter().enumerate() {
        let scene = Scene::new(drawn.mesh);
        for (v, camera) in cameras.iter().enumerate() {
            let picture = render_painted(&scene, drawn.paint, camera, tile);
            image.blit(&picture, v as u32 * (tile + gap), r as u32 * (tile + gap));
        }
    }
    image
}
