//! Small copies of stored condition views, for `sparc3d report`'s contact sheet: a view's
//! RGBA PNG decoded, composited on white (as Hunyuan3D-2.1's and Step1X-3D's loaders show
//! it) and shrunk by a box filter to at most `side` pixels a side.

/// `png` (an 8-bit RGBA view) on white, at most `side` pixels a side, as an RGB PNG. An error
/// names what is wrong with the file (not a PNG, not 8-bit RGBA).
pub fn thumbnail(png: &[u8], side: u32) -> Result<Vec<u8>, String> {
    let decoder = png::Decoder::new(std::io::Cursor::new(png));
    let mut reader = decoder.read_info().map_err(|e| format!("not a PNG: {e}"))?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| "a PNG too large to decode".to_string())?;
    let mut rgba = vec![0u8; size];
    let info = reader
        .next_frame(&mut rgba)
        .map_err(|e| format!("a damaged PNG: {e}"))?;
    if info.color_type != png::ColorType::Rgba || info.bit_depth != png::BitDepth::Eight {
        return Err(format!(
            "{:?} {:?}, not 8-bit RGBA",
            info.color_type, info.bit_depth
        ));
    }
    let (w, h) = (info.width, info.height);
    let step = w.max(h).div_ceil(side.max(1)).max(1);
    let (tw, th) = (w.div_ceil(step), h.div_ceil(step));
    let mut rgb = Vec::with_capacity((tw * th * 3) as usize);
    for ty in 0..th {
        for tx in 0..tw {
            rgb.extend(mean_on_white(&rgba, w, h, tx * step, ty * step, step));
        }
    }
    crate::encode_png(tw, th, png::ColorType::Rgb, &rgb).map_err(|e| format!("encoding: {e}"))
}

/// The mean of the block of `step` pixels a side at (`x0`, `y0`), each composited on white.
fn mean_on_white(rgba: &[u8], w: u32, h: u32, x0: u32, y0: u32, step: u32) -> [u8; 3] {
    let mut sum = [0u32; 3];
    let mut n = 0u32;
    for y in y0..(y0 + step).min(h) {
        for x in x0..(x0 + step).min(w) {
            let p = &rgba[((y * w + x) * 4) as usize..][..4];
            let a = p[3] as u32;
            for c in 0..3 {
                sum[c] += (p[c] as u32 * a + 255 * (255 - a)) / 255;
            }
            n += 1;
        }
    }
    sum.map(|s| (s / n.max(1)) as u8)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cond::picture::RgbaImage;

    #[test]
    fn a_view_shrinks_onto_white_keeping_its_colour() {
        // 8 × 8: the left half opaque red, the right half transparent.
        let mut rgba = Vec::new();
        for _ in 0..8 {
            for x in 0..8 {
                rgba.extend(if x < 4 {
                    [200, 0, 0, 255]
                } else {
                    [0, 0, 0, 0]
                });
            }
        }
        let png = RgbaImage { size: 8, rgba }.encode_png().unwrap();
        let small = thumbnail(&png, 2).unwrap();
        let mut reader = png::Decoder::new(std::io::Cursor::new(small))
            .read_info()
            .unwrap();
        let mut out = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut out).unwrap();
        assert_eq!((info.width, info.height), (2, 2));
        assert_eq!(&out[..6], &[200, 0, 0, 255, 255, 255]);
        assert!(thumbnail(b"not a png", 2)
            .unwrap_err()
            .contains("not a PNG"));
    }
}
