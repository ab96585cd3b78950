//! A material evaluated at a point of the surface, with its textures filtered over a given
//! footprint: base colour (linear RGB), metallic, roughness and alpha.
//!
//! Base colour is the material's factor × its texture (sRGB decoded) × the vertex colour;
//! alpha the product of their alphas and of the alpha map, ignored for OPAQUE (glTF 2.0
//! §3.9.5), thresholded at the cutoff for MASK; metallic and roughness the factors × their
//! texture channels. A texture on a triangle without the coordinate set it reads is skipped
//! (its factor stands alone).

use super::mips::Pyramid;
use crate::materials::{AlphaMode, Appearance, Material, ScalarMap, TextureRef};
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
        let app = self.app;
        let m = &app.materials[app.surface.material[t] as usize];
        let vc = app.surface.color.at(t).map_or([1.0; 4], |c| blend(c, bary));
        let lookup = |r: &TextureRef, srgb: bool| {
            self.lookup(t, r, srgb, bary, area * density[r.set.min(1)])
        };
        let tex = m
            .base_color_map
            .and_then(|r| lookup(&r, true))
            .unwrap_or([1.0; 4]);
        let channel = |s: &Option<ScalarMap>| {
            s.and_then(|s| Some(lookup(&s.texture, false)?[s.channel.min(3)]))
                .unwrap_or(1.0)
        };
        let rgb: [f32; 3] = std::array::from_fn(|c| m.base_color[c] * tex[c] * vc[c]);
        let alpha = alpha(m, m.base_color[3] * tex[3] * vc[3] * channel(&m.alpha_map));
        [
            rgb[0],
            rgb[1],
            rgb[2],
            m.metallic * channel(&m.metallic_map),
            m.roughness * channel(&m.roughness_map),
            alpha,
        ]
        .map(|x| x.clamp(0.0, 1.0))
    }

    /// The texture `r` at the point, filtered over `uv_area` (coordinate units²); `None`
    /// when the triangle lacks the set or the image is not there.
    fn lookup(
        &self,
        t: usize,
        r: &TextureRef,
        srgb: bool,
        bary: [f64; 3],
        uv_area: f64,
    ) -> Option<[f32; 4]> {
        let pyramid = self
            .pyramids
            .get(2 * r.image + usize::from(!srgb))?
            .as_ref()?;
        let corners = self.app.surface.uv[r.set.min(1)].at(t)?;
        let uv: [f64; 2] =
            std::array::from_fn(|k| (0..3).map(|i| bary[i] * corners[i][k] as f64).sum::<f64>());
        let m = r.transform.map(|row| row.map(f64::from));
        let uv = [0, 1].map(|k| m[k][0] * uv[0] + m[k][1] * uv[1] + m[k][2]);
        let det = (m[0][0] * m[1][1] - m[0][1] * m[1][0]).abs();
        let (w, h) = pyramid.size();
        let level = pyramid.level_for(uv_area * det * (w * h) as f64);
        Some(pyramid.sample(uv, level, r.wrap, r.nearest))
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
