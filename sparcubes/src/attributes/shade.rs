//! A material evaluated at a point of the surface, with its textures filtered over a given
//! footprint: base colour (linear RGB), metallic, roughness and alpha.
//!
//! Base colour is the material's factor × its texture (sRGB decoded) × the vertex colour;
//! alpha the product of their alphas and of the alpha map, ignored for OPAQUE (glTF 2.0
//! §3.9.5), thresholded at the cutoff for MASK; metallic and roughness the factors × their
//! texture channels. A texture on a triangle without the coordinate set it reads is skipped
//! (its factor stands alone).

use super::mips::Pyramid;
use crate::materials::{AlphaMode, Appearance, Material, ScalarMap, TextureRef, Wrap};
use rayon::prelude::*;

/// The values at a point: linear RGB, metallic, roughness, alpha.
pub type Values = [f32; 6];

/// The appearance with a mip pyramid for every image in use (colour images in linear light).
pub struct Shader<'a> {
    app: &'a Appearance,
    /// Pyramid of image `i` read as colour at `2i`, as data at `2i + 1`.
    pyramids: Vec<Option<Pyramid<'a>>>,
}

impl<'a> Shader<'a> {
    /// Builds the pyramids of the images the materials use, in parallel.
    pub fn new(app: &'a Appearance) -> Self {
        let mut wanted = vec![false; 2 * app.images.len()];
        for m in &app.materials {
            if let Some(t) = m.base_color_map {
                wanted[2 * t.image] = true;
            }
            for s in [m.metallic_map, m.roughness_map, m.alpha_map]
                .iter()
                .flatten()
            {
                wanted[2 * s.texture.image + 1] = true;
            }
        }
        let pyramids = wanted
            .par_iter()
            .enumerate()
            .map(|(k, &w)| {
                let image = app.images.get(k / 2)?.as_ref()?;
                w.then(|| Pyramid::new(image, k % 2 == 0))
            })
            .collect();
        Self { app, pyramids }
    }

    /// Texture-coordinate area per unit of surface area of triangle `t` (whose area is
    /// `area`), for each coordinate set (0 where the triangle has none).
    pub fn uv_density(&self, t: usize, area: f64) -> [f64; 2] {
        [0, 1].map(|s| match self.app.surface.uv[s].at(t) {
            Some([a, b, c]) if area > 0.0 => {
                let (u1, v1) = ((b[0] - a[0]) as f64, (b[1] - a[1]) as f64);
                let (u2, v2) = ((c[0] - a[0]) as f64, (c[1] - a[1]) as f64);
                0.5 * (u1 * v2 - u2 * v1).abs() / area
            }
            _ => 0.0,
        })
    }

    /// The values on triangle `t` at barycentric `bary`, textures filtered over a piece of
    /// `area` (grid units²) whose coordinate density is `density` ([`Shader::uv_density`]).
    pub fn at(&self, t: usize, bary: [f64; 3], area: f64, density: [f64; 2]) -> Values {
        self.prepare(t, density).at(bary, area)
    }

    /// Triangle `t`'s shading with what does not change over the triangle looked up once:
    /// its material, vertex colours and, for each texture it reads, the pyramid, coordinates
    /// and footprint scale (`density`: [`Shader::uv_density`]); its values outright when
    /// nothing varies over it. [`Prepared::at`] gives the bytes [`Shader::at`] gives.
    pub fn prepare(&self, t: usize, density: [f64; 2]) -> Prepared<'_> {
        let app = self.app;
        let m = &app.materials[app.surface.material[t] as usize];
        let lookup = |r: &TextureRef, srgb: bool| self.lookup(t, r, srgb, density);
        let scalar = |s: &Option<ScalarMap>| {
            s.and_then(|s| Some((lookup(&s.texture, false)?, s.channel.min(3))))
        };
        let metallic = scalar(&m.metallic_map);
        let roughness = scalar(&m.roughness_map);
        // glTF's metallic and roughness are two channels of one texture: read it once.
        let shared = matches!((&m.metallic_map, &m.roughness_map), (Some(a), Some(b)) if a.texture == b.texture);
        let mut prepared = Prepared {
            material: m,
            vertex_colour: app.surface.color.at(t),
            base: m.base_color_map.and_then(|r| lookup(&r, true)),
            metallic,
            roughness,
            alpha: scalar(&m.alpha_map),
            shared: shared && metallic.is_some(),
            constant: None,
        };
        if prepared.varies() {
            return prepared;
        }
        prepared.constant = Some(prepared.evaluate([1.0 / 3.0; 3], 1.0));
        prepared
    }

    /// Texture `r` as read on triangle `t` whose coordinate densities are `density`; `None`
    /// when the triangle lacks the set or the image is not there.
    fn lookup(
        &self,
        t: usize,
        r: &TextureRef,
        srgb: bool,
        density: [f64; 2],
    ) -> Option<Lookup<'_>> {
        let pyramid = self
            .pyramids
            .get(2 * r.image + usize::from(!srgb))?
            .as_ref()?;
        let corners = self.app.surface.uv[r.set.min(1)].at(t)?;
        let transform = r.transform.map(|row| row.map(f64::from));
        let det = (transform[0][0] * transform[1][1] - transform[0][1] * transform[1][0]).abs();
        let (w, h) = pyramid.size();
        Some(Lookup {
            pyramid,
            corners,
            transform,
            density: density[r.set.min(1)],
            det,
            texels: (w * h) as f64,
            wrap: r.wrap,
            nearest: r.nearest,
        })
    }
}

/// One triangle's shading, prepared by [`Shader::prepare`].
pub struct Prepared<'s> {
    material: &'s Material,
    vertex_colour: Option<[[f32; 4]; 3]>,
    base: Option<Lookup<'s>>,
    /// The metallic, roughness and alpha textures, each with the channel it reads.
    metallic: Option<(Lookup<'s>, usize)>,
    roughness: Option<(Lookup<'s>, usize)>,
    alpha: Option<(Lookup<'s>, usize)>,
    /// Whether metallic and roughness read the same texture (one lookup serves both).
    shared: bool,
    /// The values, when nothing varies over the triangle.
    constant: Option<Values>,
}

impl Prepared<'_> {
    /// The values at barycentric `bary`, textures filtered over a piece of `area` (grid
    /// units²).
    #[inline]
    pub fn at(&self, bary: [f64; 3], area: f64) -> Values {
        match self.constant {
            Some(v) => v,
            None => self.evaluate(bary, area),
        }
    }

    /// The values everywhere on the triangle, when nothing varies over it.
    pub fn constant(&self) -> Option<Values> {
        self.constant
    }

    /// Whether the values can differ from one point of the triangle to another.
    fn varies(&self) -> bool {
        self.vertex_colour.is_some()
            || self.base.is_some()
            || self.metallic.is_some()
            || self.roughness.is_some()
            || self.alpha.is_some()
    }

    /// The values at `bary` over a piece of `area`, computed.
    fn evaluate(&self, bary: [f64; 3], area: f64) -> Values {
        let m = self.material;
        let vc = self.vertex_colour.map_or([1.0; 4], |c| blend(c, bary));
        let tex = self.base.map_or([1.0; 4], |l| l.sample(bary, area));
        let channel = |s: Option<(Lookup, usize)>| s.map_or(1.0, |(l, c)| l.sample(bary, area)[c]);
        let (metallic, roughness) = match (self.shared, self.metallic, self.roughness) {
            (true, Some((l, cm)), Some((_, cr))) => {
                let texel = l.sample(bary, area);
                (texel[cm], texel[cr])
            }
            _ => (channel(self.metallic), channel(self.roughness)),
        };
        let rgb: [f32; 3] = std::array::from_fn(|c| m.base_color[c] * tex[c] * vc[c]);
        let alpha = alpha(m, m.base_color[3] * tex[3] * vc[3] * channel(self.alpha));
        [
            rgb[0],
            rgb[1],
            rgb[2],
            m.metallic * metallic,
            m.roughness * roughness,
            alpha,
        ]
        .map(|x| x.clamp(0.0, 1.0))
    }
}

/// A texture as one triangle reads it: the pyramid, the triangle's coordinates, the
/// transform and the scale from a piece's area to its footprint in texels.
#[derive(Clone, Copy)]
struct Lookup<'s> {
    pyramid: &'s Pyramid<'s>,
    corners: [[f32; 2]; 3],
    transform: [[f64; 3]; 2],
    /// Coordinate area per unit of surface area on the triangle's set.
    density: f64,
    /// The transform's area scale.
    det: f64,
    /// Level 0's texel count.
    texels: f64,
    wrap: [Wrap; 2],
    nearest: bool,
}

impl Lookup<'_> {
    /// The texture at `bary`, filtered over a piece of `area` (grid units²).
    #[inline]
    fn sample(&self, bary: [f64; 3], area: f64) -> [f32; 4] {
        let c = &self.corners;
        let uv: [f64; 2] =
            std::array::from_fn(|k| (0..3).map(|i| bary[i] * c[i][k] as f64).sum::<f64>());
        let m = &self.transform;
        let uv = [0, 1].map(|k| m[k][0] * uv[0] + m[k][1] * uv[1] + m[k][2]);
        let level = self
            .pyramid
            .level_for(area * self.density * self.det * self.texels);
        self.pyramid.sample(uv, level, self.wrap, self.nearest)
    }
}

/// A corner attribute interpolated at barycentric `b`.
fn blend(c: [[f32; 4]; 3], b: [f64; 3]) -> [f32; 4] {
    std::array::from_fn(|k| (0..3).map(|i| b[i] * c[i][k] as f64).sum::<f64>() as f32)
}

/// The stored alpha of a material whose alpha before its mode is `a`.
fn alpha(m: &Material, a: f32) -> f32 {
    match m.alpha_mode {
        AlphaMode::Opaque => 1.0,
        AlphaMode::Mask(cutoff) => f32::from(a >= cutoff),
        AlphaMode::Blend => a,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::materials::{Image, TextureRef};

    /// One triangle with texture coordinates across a 4 × 4 image of distinct texels, and a
    /// material reading `metallic` and `roughness` from it.
    fn textured(metallic: ScalarMap, roughness: ScalarMap) -> Appearance {
        let mut app = Appearance::default();
        let s = &mut app.surface;
        s.positions = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        s.triangles = vec![[0, 1, 2]];
        s.material = vec![0];
        s.uv[0].values = vec![[0.1, 0.1], [0.9, 0.2], [0.3, 0.8]];
        s.uv[0].corners = vec![[0, 1, 2]];
        app.images = vec![Some(Image {
            width: 4,
            height: 4,
            pixels: (0..16u8)
                .map(|i| [i * 15, 250 - i * 13, 40 + i * 9, 255])
                .collect(),
        })];
        let mut m = Material::default_for(false);
        (m.metallic, m.roughness) = (0.9, 0.7);
        (m.metallic_map, m.roughness_map) = (Some(metallic), Some(roughness));
        app.materials = vec![m];
        app
    }

    #[test]
    fn metallic_and_roughness_from_one_texture_read_it_once_with_the_same_values() {
        let map = |channel| ScalarMap {
            texture: TextureRef::plain(0),
            channel,
        };
        let app = textured(map(2), map(1));
        let shader = Shader::new(&app);
        let density = shader.uv_density(0, 0.5);
        let prepared = shader.prepare(0, density);
        assert!(prepared.shared && prepared.constant.is_none());
        let apart = Prepared {
            shared: false,
            ..shader.prepare(0, density)
        };
        for (bary, area) in [
            ([0.2, 0.3, 0.5], 0.01),
            ([0.6, 0.2, 0.2], 0.2),
            ([1.0, 0.0, 0.0], 1e-5),
        ] {
            let (one, two) = (prepared.at(bary, area), apart.at(bary, area));
            assert_eq!(one, two, "at {bary:?}");
            assert!(one[3] != one[4], "channels read apart: {one:?}");
        }
        // A different texture for roughness is read on its own.
        let mut other = map(1);
        other.texture.wrap = [Wrap::Clamp; 2];
        let app = textured(map(2), other);
        assert!(!Shader::new(&app).prepare(0, density).shared);
    }

    #[test]
    fn an_untextured_triangle_is_shaded_once_and_a_textured_one_at_each_point() {
        let mut app = textured(
            ScalarMap {
                texture: TextureRef::plain(0),
                channel: 2,
            },
            ScalarMap {
                texture: TextureRef::plain(0),
                channel: 1,
            },
        );
        let shader = Shader::new(&app);
        let textured = shader.prepare(0, shader.uv_density(0, 0.5));
        assert_ne!(
            textured.at([1.0, 0.0, 0.0], 0.01),
            textured.at([0.0, 0.0, 1.0], 0.01)
        );
        app.materials[0].metallic_map = None;
        app.materials[0].roughness_map = None;
        let shader = Shader::new(&app);
        let plain = shader.prepare(0, shader.uv_density(0, 0.5));
        assert_eq!(plain.constant, Some([0.8, 0.8, 0.8, 0.9, 0.7, 1.0]));
        assert_eq!(
            plain.at([0.1, 0.1, 0.8], 3.0),
            shader.at(0, [0.7, 0.2, 0.1], 0.5, [0.0; 2])
        );
    }
}
