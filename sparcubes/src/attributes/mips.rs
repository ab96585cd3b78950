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
        let fixed = srgb.then(Fixed::shared);
        let mut levels = vec![Level {
            w: image.width as usize,
            h: image.height as usize,
            texels: Cow::Borrowed(&image.pixels),
        }];
        while let Some(last) = levels.last().filter(|l| l.w > 1 || l.h > 1) {
            let next = halve(last, fixed);
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

/// Linear light in 16-bit fixed point (65,535 for 1.0): how [`halve`] averages colour.
struct Fixed {
    /// The fixed-point linear value of each sRGB byte.
    linear: [u16; 256],
    /// The sRGB byte of each fixed-point linear value.
    srgb: Vec<u8>,
}

impl Fixed {
    /// The tables, built on first use and shared by every pyramid of the process.
    fn shared() -> &'static Self {
        static FIXED: std::sync::OnceLock<Fixed> = std::sync::OnceLock::new();
        FIXED.get_or_init(|| Self::new(&decode_table(), &SrgbBytes::new()))
    }

    /// Builds both tables; the sRGB bytes are [`SrgbBytes::byte`]'s, so a mean that falls on
    /// a fixed-point value gets the byte the float path gives it.
    fn new(table: &[f32; 256], bytes: &SrgbBytes) -> Self {
        let scale = f32::from(u16::MAX);
        Self {
            linear: table.map(|l| (l * scale).round() as u16),
            srgb: (0..=u16::MAX)
                .map(|i| bytes.byte(f32::from(i) / scale))
                .collect(),
        }
    }
}

/// The next level of `l`: each texel the mean of (up to) 2×2 texels, its rows in parallel
/// (each row computed alone, so the texels do not depend on the threads). Colour channels
/// are averaged in 16-bit fixed-point linear light (a step of 1/65,535, a twentieth of the
/// darkest sRGB step), the others as bytes; both round the mean to the nearest, halves up.
/// Integers and two table lookups a channel: a 2048² texture's pyramid was an eighth of its
/// item's sampling time with a float mean and an sRGB encoding per channel.
fn halve(l: &Level, fixed: Option<&Fixed>) -> Level<'static> {
    let (w, h) = ((l.w / 2).max(1), (l.h / 2).max(1));
    let mut texels = vec![[0u8; 4]; w * h];
    let row = |y: usize| &l.texels[y.min(l.h - 1) * l.w..][..l.w];
    texels.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let (top, bottom) = (row(2 * y), row(2 * y + 1));
        for (x, texel) in out.iter_mut().enumerate() {
            let (x0, x1) = (2 * x, (2 * x + 1).min(l.w - 1));
            let four = [top[x0], top[x1], bottom[x0], bottom[x1]];
            *texel = std::array::from_fn(|c| match fixed {
                Some(f) if c < 3 => {
                    let sum: u32 = four
                        .iter()
                        .map(|t| u32::from(f.linear[t[c] as usize]))
                        .sum();
                    f.srgb[((sum + 2) / 4) as usize]
                }
                _ => ((four.iter().map(|t| u32::from(t[c])).sum::<u32>() + 2) / 4) as u8,
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
    fn halving_in_fixed_point_matches_the_float_mean_of_linear_light() {
        // Every texel of a 2×2 block's mean against the mean of the decoded floats, on
        // pseudo-random blocks (a fixed linear congruential sequence).
        let table = decode_table();
        let bytes = SrgbBytes::new();
        let fixed = Fixed::new(&table, &bytes);
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as u8
        };
        let (mut differ, blocks) = (0, 20_000);
        for _ in 0..blocks {
            let pixels: Vec<[u8; 4]> = (0..4).map(|_| [next(), next(), next(), next()]).collect();
            let image = Image {
                width: 2,
                height: 2,
                pixels: pixels.clone(),
            };
            let level = Level {
                w: 2,
                h: 2,
                texels: Cow::Borrowed(&image.pixels),
            };
            let got = halve(&level, Some(&fixed)).texels[0];
            for c in 0..4 {
                let want = if c < 3 {
                    let mean = pixels.iter().map(|t| table[t[c] as usize]).sum::<f32>() / 4.0;
                    bytes.byte(mean)
                } else {
                    to_byte(pixels.iter().map(|t| f32::from(t[c]) / 255.0).sum::<f32>() / 4.0)
                };
                assert!(
                    got[c].abs_diff(want) <= 1,
                    "{pixels:?} channel {c}: {got:?}"
                );
                differ += usize::from(got[c] != want);
            }
        }
        assert!(
            differ * 1000 < blocks * 4,
            "{differ} of {} channels differ",
            blocks * 4
        );
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
