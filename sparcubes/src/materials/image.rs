//! Texture images decoded to 8-bit RGBA: PNG through `png` (the crate the preview pictures
//! already use), JPEG through `zune-jpeg` (pure Rust, fuzzed, the JPEG decoder of the `image`
//! crate). The size is read from the header first and an image over [`MAX_PIXELS`] is refused
//! before any pixel is allocated, so a 16384² texture costs a header read, not a gigabyte.

use png::{ColorType, Transformations};

/// Most pixels an image may have: 8192² (256 MiB as RGBA). Textures of 4096² and 8192² are
/// what production assets ship; 16384² (1 GiB decoded, plus its mip levels) would put one
/// item's memory near the worker's default limit of 8 GiB (`limits.item_memory_bytes`).
pub const MAX_PIXELS: u64 = 8192 * 8192;

/// The first bytes of every PNG file.
const PNG_SIGNATURE: [u8; 4] = [0x89, b'P', b'N', b'G'];

/// Largest texture file read: an image of [`MAX_PIXELS`] in 16-bit RGBA stored without
/// compression, plus a MiB of other chunks. A larger file cannot hold an image that decodes
/// here, so it is refused from its length before it is read.
pub const MAX_FILE_BYTES: u64 = MAX_PIXELS * 8 + (1 << 20);

/// Why a texture file of `len` bytes whose first bytes are `head` is not read further:
/// longer than [`MAX_FILE_BYTES`], or a PNG whose header (its first 24 bytes) names more than
/// [`MAX_PIXELS`]. `None` when it may be read.
pub fn refusal(head: &[u8], len: u64) -> Option<String> {
    if len > MAX_FILE_BYTES {
        return Some(format!(
            "the file is {len} bytes, more than any image of at most {MAX_PIXELS} pixels \
             (8192²) needs; not read"
        ));
    }
    let png = head.starts_with(&PNG_SIGNATURE) && head.get(12..16) == Some(b"IHDR");
    let word = |at: usize| {
        head.get(at..at + 4)
            .map(|b| u32::from_be_bytes([b[0], b[1], b[2], b[3]]) as u64)
    };
    match (png, word(16), word(20)) {
        (true, Some(w), Some(h)) => check_size(w, h, MAX_PIXELS)
            .err()
            .map(|e| format!("PNG: {e}")),
        _ => None,
    }
}

/// A decoded image: 8-bit RGBA, rows top to bottom.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels (at least 1).
    pub width: u32,
    /// Height in pixels (at least 1).
    pub height: u32,
    /// `width × height` pixels, row-major from the top row.
    pub pixels: Vec<[u8; 4]>,
}

/// Fails when `width × height` is zero, over [`MAX_PIXELS`], or over `limit` (what is left
/// of the item's texture budget, [`super::TextureBudget`]).
fn check_size(width: u64, height: u64, limit: u64) -> Result<(), String> {
    if width == 0 || height == 0 {
        return Err(format!("{width}×{height} pixels: an empty image"));
    }
    let pixels = width * height;
    if pixels > MAX_PIXELS {
        return Err(format!(
            "{width}×{height} pixels, over the limit of {MAX_PIXELS} (8192²); not decoded"
        ));
    }
    if pixels > limit {
        return Err(format!(
            "{width}×{height} pixels, more than the {limit} pixels left of the item's texture \
             budget (a quarter of --item-memory); not decoded"
        ));
    }
    Ok(())
}

/// Decodes a PNG or JPEG image (told apart by their signatures); the error says why not.
pub fn decode(bytes: &[u8]) -> Result<Image, String> {
    decode_within(bytes, MAX_PIXELS)
}

/// Decodes a PNG or JPEG image of at most `limit` pixels (and never over [`MAX_PIXELS`]),
/// refused from its header otherwise.
pub(crate) fn decode_within(bytes: &[u8], limit: u64) -> Result<Image, String> {
    if bytes.starts_with(&PNG_SIGNATURE) {
        decode_png(bytes, limit).map_err(|e| format!("PNG: {e}"))
    } else if bytes.starts_with(&[0xFF, 0xD8]) {
        decode_jpeg(bytes, limit).map_err(|e| format!("JPEG: {e}"))
    } else {
        Err("neither PNG nor JPEG (other image formats are not read)".into())
    }
}

fn decode_png(bytes: &[u8], limit: u64) -> Result<Image, String> {
    let limits = png::Limits {
        bytes: (MAX_PIXELS as usize) * 8 + (1 << 20),
    };
    let mut decoder = png::Decoder::new_with_limits(std::io::Cursor::new(bytes), limits);
    decoder.set_transformations(Transformations::normalize_to_color8());
    let header = decoder.read_header_info().map_err(|e| e.to_string())?;
    check_size(header.width as u64, header.height as u64, limit)?;
    let mut reader = decoder.read_info().map_err(|e| e.to_string())?;
    let size = reader
        .output_buffer_size()
        .ok_or("the decoded image would not fit in memory")?;
    let mut buf = vec![0u8; size];
    let frame = reader.next_frame(&mut buf).map_err(|e| e.to_string())?;
    let (w, h) = (frame.width, frame.height);
    let data = &buf[..frame.buffer_size()];
    let pixels: Vec<[u8; 4]> = match frame.color_type {
        ColorType::Rgba => data
            .chunks_exact(4)
            .map(|p| [p[0], p[1], p[2], p[3]])
            .collect(),
        ColorType::Rgb => data
            .chunks_exact(3)
            .map(|p| [p[0], p[1], p[2], 255])
            .collect(),
        ColorType::GrayscaleAlpha => data
            .chunks_exact(2)
            .map(|p| [p[0], p[0], p[0], p[1]])
            .collect(),
        ColorType::Grayscale => data.iter().map(|&g| [g, g, g, 255]).collect(),
        ColorType::Indexed => return Err("palette not expanded".into()),
    };
    finish(w, h, pixels)
}

/// Checks that `pixels` holds `w × h` pixels.
fn finish(w: u32, h: u32, pixels: Vec<[u8; 4]>) -> Result<Image, String> {
    if pixels.len() as u64 != w as u64 * h as u64 {
        return Err(format!(
            "{} pixels decoded for a {w}×{h} image",
            pixels.len()
        ));
    }
    Ok(Image {
        width: w,
        height: h,
        pixels,
    })
}

fn decode_jpeg(bytes: &[u8], limit: u64) -> Result<Image, String> {
    use zune_jpeg::zune_core::colorspace::ColorSpace;
    use zune_jpeg::zune_core::options::DecoderOptions;
    let options = DecoderOptions::default()
        .jpeg_set_out_colorspace(ColorSpace::RGBA)
        .set_max_width(1 << 16)
        .set_max_height(1 << 16);
    let mut decoder =
        zune_jpeg::JpegDecoder::new_with_options(std::io::Cursor::new(bytes), options);
    decoder.decode_headers().map_err(|e| format!("{e:?}"))?;
    let (w, h) = decoder
        .dimensions()
        .ok_or("no dimensions after the header")?;
    check_size(w as u64, h as u64, limit)?;
    let data = decoder.decode().map_err(|e| format!("{e:?}"))?;
    let pixels = data
        .chunks_exact(4)
        .map(|p| [p[0], p[1], p[2], p[3]])
        .collect();
    finish(w as u32, h as u32, pixels)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A PNG of `w × h` RGBA pixels from `pixel(x, y)`.
    pub(crate) fn png_bytes(w: u32, h: u32, pixel: impl Fn(u32, u32) -> [u8; 4]) -> Vec<u8> {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(ColorType::Rgba);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header().expect("png header");
        let mut data = Vec::new();
        for y in 0..h {
            for x in 0..w {
                data.extend(pixel(x, y));
            }
        }
        writer.write_image_data(&data).expect("png data");
        drop(writer);
        out
    }

    #[test]
    fn a_png_decodes_to_its_pixels() {
        let bytes = png_bytes(3, 2, |x, y| [x as u8 * 10, y as u8 * 20, 7, 200]);
        let im = decode(&bytes).expect("decodes");
        assert_eq!((im.width, im.height), (3, 2));
        assert_eq!(im.pixels[5], [20, 20, 7, 200]);
    }

    #[test]
    fn a_truncated_png_is_an_error_not_a_panic() {
        let bytes = png_bytes(16, 16, |x, _| [x as u8, 0, 0, 255]);
        let err = decode(&bytes[..bytes.len() / 2]).expect_err("truncated");
        assert!(err.starts_with("PNG:"), "{err}");
    }

    #[test]
    fn a_huge_png_is_refused_from_its_header() {
        // A valid signature and IHDR of 16384², and nothing after: refused by its size alone.
        let mut bytes = png_bytes(1, 1, |_, _| [0; 4]);
        bytes[16..20].copy_from_slice(&16384u32.to_be_bytes());
        bytes[20..24].copy_from_slice(&16384u32.to_be_bytes());
        let crc = png_crc(&bytes[12..29]);
        bytes[29..33].copy_from_slice(&crc.to_be_bytes());
        let err = decode(&bytes[..33]).expect_err("too large");
        assert!(
            err.contains("16384×16384") && err.contains("limit"),
            "{err}"
        );
    }

    /// CRC-32 (PNG's chunk checksum) of `data`.
    fn png_crc(data: &[u8]) -> u32 {
        let mut c = 0xFFFF_FFFFu32;
        for &b in data {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
        }
        !c
    }

    #[test]
    fn a_corrupt_jpeg_is_an_error_not_a_panic() {
        let bytes = [
            0xFF, 0xD8, 0xFF, 0xE0, 0, 16, b'J', b'F', b'I', b'F', 0, 1, 2, 3,
        ];
        let err = decode(&bytes).expect_err("corrupt");
        assert!(err.starts_with("JPEG:"), "{err}");
    }
}
