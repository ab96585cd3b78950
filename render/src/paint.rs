//! Colours for the front faces of a drawn mesh: the base colour of the point a pixel sees,
//! which [`crate::render_painted`] lights as it lights the plain grey-blue.
//!
//! [`VertexColours`] paints a mesh whose vertices carry colours (the output mesh coloured as
//! `convert --attributes` colours it: each vertex its cell's base colour), blended across each
//! triangle as a viewer of the written PLY blends them. [`SurfaceColours`] paints a source
//! from its appearance (materials, textures, vertex colours) as the attribute sampler reads
//! it ([`sparcubes::attributes::shade`]), textures filtered over a pixel's footprint.

use sparcubes::attributes::shade::Shader;
use sparcubes::colour::{linear_to_srgb, to_byte};
use sparcubes::materials::Appearance;

/// The base colour (sRGB bytes) of every point of a mesh's surface.
pub trait Paint: Sync {
    /// The colour at barycentric coordinates `bary` of triangle `triangle` (an index into
    /// the drawn mesh's triangles).
    fn colour(&self, triangle: usize, bary: [f32; 3]) -> [u8; 3];
}

/// Colours per vertex (sRGB RGBA bytes, alpha not drawn), blended across each triangle.
pub struct VertexColours<'a> {
    /// The drawn mesh's triangles.
    pub triangles: &'a [[u32; 3]],
    /// One colour per vertex of the drawn mesh.
    pub colours: &'a [[u8; 4]],
}

impl Paint for VertexColours<'_> {
    fn colour(&self, triangle: usize, bary: [f32; 3]) -> [u8; 3] {
        let Some(tri) = self.triangles.get(triangle) else {
            return crate::FRONT;
        };
        let corner = |k: usize| self.colours.get(tri[k] as usize).copied();
        let (Some(a), Some(b), Some(c)) = (corner(0), corner(1), corner(2)) else {
            return crate::FRONT;
        };
        std::array::from_fn(|ch| {
            let v = bary[0] * a[ch] as f32 + bary[1] * b[ch] as f32 + bary[2] * c[ch] as f32;
            v.round().clamp(0.0, 255.0) as u8
        })
    }
}

/// A source's appearance: the drawn mesh is its surface (`appearance.surface`'s positions and
/// triangles, so triangle numbers agree).
pub struct SurfaceColours<'a> {
    shader: Shader<'a>,
    /// Area of each triangle of the surface (source units²).
    areas: Vec<f64>,
    /// Area one pixel covers (source units²): the footprint textures are filtered over.
    pixel_area: f64,
}

impl<'a> SurfaceColours<'a> {
    /// Paints `appearance` seen at `pixel_size` source units per pixel.
    pub fn new(appearance: &'a Appearance, pixel_size: f64) -> Self {
        Self {
            shader: Shader::new(appearance),
            areas: triangle_areas(appearance),
            pixel_area: pixel_size * pixel_size,
        }
    }
}

/// The area of each triangle of `appearance`'s surface (source units²; a corner with an index
/// out of range counts as the origin).
pub(crate) fn triangle_areas(appearance: &Appearance) -> Vec<f64> {
    let s = &appearance.surface;
    s.triangles
        .iter()
        .map(|t| {
            let p = t.map(|i| {
                s.positions
                    .get(i as usize)
                    .map_or([0.0; 3], |p| p.map(f64::from))
            });
            let (u, v) = (sub(p[1], p[0]), sub(p[2], p[0]));
            let c = [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ];
            0.5 * (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt()
        })
        .collect()
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

impl Paint for SurfaceColours<'_> {
    fn colour(&self, triangle: usize, bary: [f32; 3]) -> [u8; 3] {
        let Some(&area) = self.areas.get(triangle) else {
            return crate::FRONT;
        };
        let density = self.shader.uv_density(triangle, area);
        let v = self
            .shader
            .at(triangle, bary.map(f64::from), self.pixel_area, density);
        [v[0], v[1], v[2]].map(|c| to_byte(linear_to_srgb(c)))
    }
}
