//! Mip pyramids of texture images and filtered lookups in them.
//!
//! Each level halves the one before (a box filter over 2×2 texels, the last row or column
//! repeated for odd sizes), averaged in linear light for colour images (sRGB decoded, averaged,
//! encoded again) and as stored for data images (metallic, roughness, alpha maps). Levels are
//! kept as 8-bit texels: a pyramid costs a third of its image again. A lookup is trilinear:
//! bilinear in the two levels around the requested one, blended by its fraction; at level 0
//! with a NEAREST magnification filter it is the nearest texel.

pub use crate::colour::{linear_to_srgb, to_byte};

use crate::colour::SrgbBytes;
use rayon::prelude::*;

use crate::materials::{Image, Wrap};
use std::borrow::Cow;

/// sRGB byte → linear value, for every byte.
fn decode_table() -> [f32; 256] {
    std::array::from_fn(|i| crate::materials::srgb_to_linear(i as f32 / 255.0))
}

/// One level: its size and texels, rows from the top.
#[derive(Debug, Clone)]
struct Level<'a> {
    w: usize,
    h: usize,
    texels: Cow<'a, [[u8; 4]]>,
}

/// An image's mip levels, level 0 the image itself.
#[derive(Debug, Clone)]
pub struct Pyramid<'a> {
    levels: Vec<Level<'a>>,
    /// Whether the first three channels are sRGB (decoded to linear by lookups).
    srgb: bool,
    table: [f32; 256],
}

impl<'a> Pyramid<'a> {
    /// Builds the pyramid of `image`, averaging colour channels in linear light when `srgb`.
    pub fn new(image: &'a Image, srgb: bool) -> Self {
        let table = decode_table();
        let bytes = SrgbBytes::new();
        let mut levels = vec![Level {
            w: image.width as usize,
            h: image.height as usize,
            texels: Cow::Borrowed(&image.pixels),
        }];
        while let Some(last) = levels.last().filter(|l| l.w > 1 || l.h > 1) {
            let next = halve(last, srgb, &table, &bytes);
            levels.push(next);
        }
        Self {
            levels,
            srgb,
            table,
        }
    }

    /// Number of levels.
    pub fn len(&self) -> usize {
        self.levels.len()
    }

    /// Whether the pyramid has no level (never: an image has at least one texel).
    pub fn is_empty(&self) -> bool {
        self.levels.is_empty()
    }

    /// Width and height of level 0.
    pub fn size(&self) -> (usize, usize) {
        (self.levels[0].w, self.levels[0].h)
    }

    /// The level whose texel matches a footprint of `texels` level-0 texels (its area).
    pub fn level_for(&self, texels: f64) -> f32 {
        if texels.is_finite() && texels > 1.0 {
            (0.5 * texels.log2()) as f32
        } else {
            0.0
        }
    }

    /// The filtered value at `uv` (glTF convention: v down the image) and `level`, linear
    /// RGBA.
    pub fn sample(&self, uv: [f64; 2], level: f32, wrap: [Wrap; 2], nearest: bool) -> [f32; 4] {
        let top = (self.levels.len() - 1) as f32;
        let level = if level.is_finite() {
            level.clamp(0.0, top)
        } else {
            0.0
        };
        if level <= 0.0 && nearest {
            return self.texel(&self.levels[0], uv, wrap);
        }
        let lo = level.floor() as usize;
        let f = level - lo as f32;
        let a = self.bilinear(&self.levels[lo], uv, wrap);
        if f == 0.0 || lo + 1 >= self.levels.len() {
            return a;
        }
        let b = self.bilinear(&self.levels[lo + 1], uv, wrap);
        std::array::from_fn(|c| a[c] * (1.0 - f) + b[c] * f)
    }

    fn decode(&self, t: [u8; 4]) -> [f32; 4] {
        if self.srgb {
            [
                self.table[t[0] as usize],
                self.table[t[1] as usize],
                self.table[t[2] as usize],
                t[3] as f32 / 255.0,
            ]
        } else {
            t.map(|c| c as f32 / 255.0)
        }
    }

    fn texel(&self, l: &Level, uv: [f64; 2], wrap: [Wrap; 2]) -> [f32; 4] {
        let (u, v) = finite(uv);
        let x = wrap_index((u * l.w as f64).floor(), l.w, wrap[0]);
        let y = wrap_index((v * l.h as f64).floor(), l.h, wrap[1]);
        self.decode(l.texels[y * l.w + x])
    }

    fn bilinear(&self, l: &Level, uv: [f64; 2], wrap: [Wrap; 2]) -> [f32; 4] {
        let (u, v) = finite(uv);
        let (x, y) = (u * l.w as f64 - 0.5, v * l.h as f64 - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let xs = [
            wrap_index(x0, l.w, wrap[0]),
            wrap_index(x0 + 1.0, l.w, wrap[0]),
        ];
        let ys = [
            wrap_index(y0, l.h, wrap[1]),
            wrap_index(y0 + 1.0, l.h, wrap[1]),
        ];
        let at = |i: usize, j: usize| self.decode(l.texels[ys[j] * l.w + xs[i]]);
        let (a, b, c, d) = (at(0, 0), at(1, 0), at(0, 1), at(1, 1));
        std::array::from_fn(|k| {
            let top = a[k] * (1.0 - fx) + b[k] * fx;
            let bottom = c[k] * (1.0 - fx) + d[k] * fx;
            top * (1.0 - fy) + bottom * fy
        })
    }
}

/// Texture coordinates with anything non-finite read as 0.
fn finite(uv: [f64; 2]) -> (f64, f64) {
    let f = |x: f64| if x.is_finite() { x } else { 0.0 };
    (f(uv[0]), f(uv[1]))
}

/// A texel index `i` (any integer, as a float; saturated to the 64-bit range, NaN read as
/// 0) wrapped into `0..n`, in integers: a float remainder costs a library call a texel.
fn wrap_index(i: f64, n: usize, wrap: Wrap) -> usize {
    let n = n.max(1) as i64;
    let i = i as i64;
    if (0..n).contains(&i) {
        return i as usize;
    }
    let r = match wrap {
        Wrap::Clamp => i.clamp(0, n - 1),
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::Mirror => {
            let m = i.rem_euclid(2 * n);
            if m < n {
                m
            } else {
                2 * n - 1 - m
            }
        }
    };
    r as usize
}

/// The next level of `l`: each texel the mean of (up to) 2×2 texels, its rows in parallel
/// (each row computed alone, so the texels do not depend on the threads).
fn halve(l: &Level, srgb: bool, table: &[f32; 256], bytes: &SrgbBytes) -> Level<'static> {
    let (w, h) = ((l.w / 2).max(1), (l.h / 2).max(1));
    let mut texels = vec![[0u8; 4]; w * h];
    texels.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, out) in row.iter_mut().enumerate() {
            let mut sum = [0.0f32; 4];
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let sx = (2 * x + dx).min(l.w - 1);
                let sy = (2 * y + dy).min(l.h - 1);
                let t = l.texels[sy * l.w + sx];
                for c in 0..4 {
                    sum[c] += if srgb && c < 3 {
                        table[t[c] as usize]
                    } else {
                        t[c] as f32 / 255.0
                    };
                }
            }
            *out = std::array::from_fn(|c| {
                let mean = sum[c] / 4.0;
                if srgb && c < 3 {
                    bytes.byte(mean)
                } else {
                    to_byte(mean)
                }
            });
        }
    });
    Level {
        w,
        h,
        texels: Cow::Owned(texels),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker(n: u32) -> Image {
        let pixels = (0..n * n)
            .map(|i| {
                let (x, y) = (i % n, i / n);
                if (x + y) % 2 == 0 {
                    [255, 255, 255, 255]
                } else {
                    [0, 0, 0, 255]
                }
            })
            .collect();
        Image {
            width: n,
            height: n,
            pixels,
        }
    }

    #[test]
    fn a_checker_averages_to_half_in_linear_light() {
        let image = checker(8);
        let p = Pyramid::new(&image, true);
        assert_eq!(p.len(), 4);
        let top = p.sample([0.3, 0.7], 3.0, [Wrap::Repeat; 2], false);
        // Half white, half black averages to 0.5 linear (sRGB 188), not to sRGB 128.
        assert!((top[0] - 0.5).abs() < 0.01, "{top:?}");
        let texel = p.sample([0.5 / 8.0, 0.5 / 8.0], 0.0, [Wrap::Repeat; 2], true);
        assert_eq!(texel, [1.0; 4]);
    }

    #[test]
    fn wraps_repeat_clamp_and_mirror() {
        assert_eq!(wrap_index(-1.0, 4, Wrap::Repeat), 3);
        assert_eq!(wrap_index(-1.0, 4, Wrap::Clamp), 0);
        assert_eq!(wrap_index(-1.0, 4, Wrap::Mirror), 0);
        assert_eq!(wrap_index(5.0, 4, Wrap::Mirror), 2);
        assert_eq!(wrap_index(1e12 + 1.0, 4, Wrap::Repeat), 1);
    }
}
