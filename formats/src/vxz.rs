//! o_voxel's `.vxz` container of sparse voxels with `u8` attributes, as TRELLIS.2's
//! `o-voxel/o_voxel/io/vxz.py` `read_vxz` (L143-220) reads it:
//!
//! - `VXZ`, a version byte 0, then the big-endian `u32` offset of the binary part
//!   (8 + the JSON header's length), the UTF-8 JSON header, and the binary part
//!   (`write_vxz` L352-365);
//! - the voxels are cut into chunks of `chunk_size`³ (`coord // chunk_size`, L277-278); each
//!   chunk stores its voxels as a sparse voxel octree over their local Morton codes
//!   (`o-voxel/src/io/svo.cpp` L17-76: one occupancy byte per node, depth-first pre-order,
//!   children in ascending order, no bytes for the voxels themselves), then each attribute's
//!   rows in the same ascending Morton order (L295-299, `as_is`: voxel-major);
//! - every stream is compressed on its own: here one zstd frame carrying its content size
//!   (`zstd::bulk`), which `_decompress` (L93-94, python-zstandard's `decompress`) needs;
//! - the header lists, per chunk, `idx` (chunk index), `ptr` (`[offset, length]` of the
//!   chunk's bytes in the binary part) and `[offset, length]` of `svo` and of each attribute
//!   within the chunk's bytes (L332-347); `attr` is a list of `[name, channels]` (L267).

use crate::error::{Error, Result};
use serde_json::{json, Value};

/// The chunk side TRELLIS.2's writers use (`write_vxz`'s default, L229).
pub const CHUNK_SIZE: u32 = 256;

/// zstd level of every stream (the reader ignores it for zstd, `_decompress` L93-94).
const ZSTD_LEVEL: i32 = 9;

/// One attribute: `channels` bytes per voxel, voxel-major, in the order of the voxels given.
#[derive(Debug, Clone, Copy)]
pub struct Attr<'a> {
    /// Its name (a key of each chunk in the header).
    pub name: &'a str,
    /// Bytes per voxel.
    pub channels: usize,
    /// `channels` bytes per voxel.
    pub data: &'a [u8],
}

/// The Morton (Z-order) code of a local coordinate (each axis below 1024), as o_voxel's
/// `z_order_encode` (`o-voxel/src/serialize/z_order.cu` L11-47): bit `b` of x, y, z at
/// `3b + 2`, `3b + 1`, `3b`.
pub fn morton(c: [u32; 3]) -> u32 {
    let mut code = 0;
    for b in 0..10 {
        code |= (c[0] >> b & 1) << (3 * b + 2);
        code |= (c[1] >> b & 1) << (3 * b + 1);
        code |= (c[2] >> b & 1) << (3 * b);
    }
    code
}

/// The sparse voxel octree bytes of `codes` (unique, ascending Morton codes of a chunk of
/// depth `depth`): one occupancy byte per node, depth-first pre-order (svo.cpp L17-76).
pub fn svo_bytes(codes: &[u32], depth: u32) -> Vec<u8> {
    let mut out = Vec::new();
    node(codes, 0, depth, &mut out);
    out
}

/// Writes the node holding `codes` at `level` and, below the last level, its children.
fn node(codes: &[u32], level: u32, depth: u32, out: &mut Vec<u8>) {
    let shift = 3 * (depth - 1 - level);
    let child = |c: u32| (c >> shift & 7) as u8;
    out.push(codes.iter().fold(0u8, |m, &c| m | 1 << child(c)));
    if level + 1 == depth {
        return;
    }
    let mut start = 0;
    while start < codes.len() {
        let first = child(codes[start]);
        let len = codes[start..].partition_point(|&c| child(c) == first);
        node(&codes[start..start + len], level + 1, depth, out);
        start += len;
    }
}

/// The `.vxz` bytes of `coords` (unique, non-negative) with `attrs`, in chunks of
/// `chunk_size` (a power of two, at least 2). Refuses an empty grid (`read_vxz` fails on
/// one, L217), repeated voxels (their attribute rows would be misaligned) and attributes of
/// the wrong length.
pub fn vxz_bytes(coords: &[[u32; 3]], attrs: &[Attr], chunk_size: u32) -> Result<Vec<u8>> {
    check(coords, attrs, chunk_size)?;
    let depth = chunk_size.trailing_zeros();
    // Voxels by chunk, then by local Morton code: one 48-bit key, the chunk's coordinates
    // (16 − depth bits each) above the Morton code (3 × depth bits), computed once per voxel
    // and sorted with its index beside it.
    let side_bits = 16 - depth;
    let key = |c: &[u32; 3]| -> u64 {
        let chunk = c.map(|v| u64::from(v >> depth));
        let chunk = chunk[0] << (2 * side_bits) | chunk[1] << side_bits | chunk[2];
        chunk << (3 * depth) | u64::from(morton(c.map(|v| v % chunk_size)))
    };
    let mut keyed: Vec<(u64, usize)> = coords.iter().map(key).zip(0..coords.len()).collect();
    keyed.sort_unstable();
    let (keys, order): (Vec<u64>, Vec<usize>) = keyed.into_iter().unzip();
    let chunk_of = |k: u64| -> [u64; 3] {
        let c = k >> (3 * depth);
        let mask = (1u64 << side_bits) - 1;
        [c >> (2 * side_bits), c >> side_bits & mask, c & mask]
    };
    let code_of = |k: u64| (k & ((1u64 << (3 * depth)) - 1)) as u32;
    if order.windows(2).any(|w| coords[w[0]] == coords[w[1]]) {
        return Err(Error::Invalid("a voxel is listed twice".into()));
    }
    let mut blob = Vec::new();
    let mut chunks = Vec::new();
    let mut start = 0;
    while start < order.len() {
        let chunk = keys[start] >> (3 * depth);
        let len = keys[start..].partition_point(|k| k >> (3 * depth) == chunk);
        let members = &order[start..start + len];
        let codes: Vec<u32> = keys[start..start + len]
            .iter()
            .map(|&k| code_of(k))
            .collect();
        let mut entry = serde_json::Map::new();
        entry.insert("idx".into(), json!(chunk_of(keys[start])));
        let at = blob.len();
        push_stream(&mut blob, at, "svo", &svo_bytes(&codes, depth), &mut entry)?;
        for a in attrs {
            let rows: Vec<u8> = members
                .iter()
                .flat_map(|&i| &a.data[i * a.channels..(i + 1) * a.channels])
                .copied()
                .collect();
            push_stream(&mut blob, at, a.name, &rows, &mut entry)?;
        }
        entry.insert("ptr".into(), json!([at, blob.len() - at]));
        chunks.push(Value::Object(entry));
        start += len;
    }
    let raw_size = coords.len() * 12 + attrs.iter().map(|a| a.data.len()).sum::<usize>();
    let header = json!({
        "num_voxel": coords.len(),
        "chunk_size": chunk_size,
        "filter": "none",
        "compression": "zstd",
        "compression_level": ZSTD_LEVEL,
        "raw_size": raw_size,
        "compressed_size": blob.len(),
        "compress_ratio": raw_size as f64 / blob.len().max(1) as f64,
        "attr_interleave": "as_is",
        "attr": attrs.iter().map(|a| json!([a.name, a.channels])).collect::<Vec<_>>(),
        "chunks": chunks,
    });
    container(&header, &blob)
}

/// Refuses what `read_vxz` cannot read back as it was given.
fn check(coords: &[[u32; 3]], attrs: &[Attr], chunk_size: u32) -> Result<()> {
    if coords.is_empty() {
        return Err(Error::Invalid("no voxel to write".into()));
    }
    if !chunk_size.is_power_of_two() || !(2..=1024).contains(&chunk_size) {
        return Err(Error::Invalid(format!(
            "chunk size {chunk_size} is not a power of two in 2..=1024"
        )));
    }
    if let Some(c) = coords
        .iter()
        .find(|c| c.iter().any(|&v| v > u32::from(u16::MAX)))
    {
        return Err(Error::Invalid(format!(
            "voxel {c:?} lies beyond the largest grid sparc3d writes (65536 per axis)"
        )));
    }
    for a in attrs {
        if a.channels == 0 || a.data.len() != coords.len() * a.channels {
            return Err(Error::Invalid(format!(
                "attribute {} holds {} bytes, not {} voxels × {} channels",
                a.name,
                a.data.len(),
                coords.len(),
                a.channels
            )));
        }
    }
    Ok(())
}

/// Appends `bytes` compressed to `blob` and records `[offset, length]` (from `chunk_start`)
/// under `name`.
fn push_stream(
    blob: &mut Vec<u8>,
    chunk_start: usize,
    name: &str,
    bytes: &[u8],
    entry: &mut serde_json::Map<String, Value>,
) -> Result<()> {
    let frame = zstd::bulk::compress(bytes, ZSTD_LEVEL)
        .map_err(|e| Error::Invalid(format!("compressing {name}: {e}")))?;
    entry.insert(name.into(), json!([blob.len() - chunk_start, frame.len()]));
    blob.extend_from_slice(&frame);
    Ok(())
}

/// `VXZ`, version 0, the big-endian offset of the binary part, the header, the binary part.
fn container(header: &Value, blob: &[u8]) -> Result<Vec<u8>> {
    let text = serde_json::to_vec(header)
        .map_err(|e| Error::Invalid(format!("writing the vxz header: {e}")))?;
    let start = u32::try_from(text.len() + 8)
        .map_err(|_| Error::TooLarge("the vxz header exceeds 4 GiB".into()))?;
    let mut out = Vec::with_capacity(8 + text.len() + blob.len());
    out.extend_from_slice(b"VXZ\0");
    out.extend_from_slice(&start.to_be_bytes());
    out.extend_from_slice(&text);
    out.extend_from_slice(blob);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_codes_put_x_highest() {
        assert_eq!(morton([1, 0, 0]), 4);
        assert_eq!(morton([0, 1, 0]), 2);
        assert_eq!(morton([0, 0, 1]), 1);
        assert_eq!(morton([2, 0, 0]), 32);
        assert_eq!(morton([3, 3, 3]), 63);
        assert_eq!(
            morton([1023, 0, 0]),
            0b100_100_100_100_100_100_100_100_100_100
        );
    }

    #[test]
    fn the_octree_of_a_hand_example() {
        // Chunk of 4 (depth 2): (0,0,0), (1,0,0), (2,0,0) → codes 0, 4, 32. The root has
        // children 0 and 4; node 0 holds codes 0 and 4; node 4 holds code 32 (child 0).
        assert_eq!(svo_bytes(&[0, 4, 32], 2), vec![0x11, 0x11, 0x01]);
        // One voxel in a chunk of 256 takes 8 bytes, one per level.
        assert_eq!(svo_bytes(&[morton([255, 0, 0])], 8), vec![0x10; 8]);
    }

    /// Decompresses stream `[offset, length]` of a chunk.
    fn stream(chunk: &[u8], at: &Value) -> Vec<u8> {
        let (o, l) = (at[0].as_u64().unwrap_or(0), at[1].as_u64().unwrap_or(0));
        let frame = &chunk[o as usize..(o + l) as usize];
        let size = zstd::zstd_safe::get_frame_content_size(frame)
            .ok()
            .flatten();
        assert_eq!(
            size.map(|s| s > 0),
            Some(true),
            "no content size in the frame"
        );
        zstd::bulk::decompress(frame, 1 << 20).unwrap_or_default()
    }

    #[test]
    fn the_container_splits_chunks_and_orders_rows_by_morton_code() {
        // Three voxels in two chunks of 4, given out of order, with a 1-channel attribute.
        let coords = [[2, 0, 0], [5, 1, 0], [0, 0, 0]];
        let attr = [Attr {
            name: "a",
            channels: 1,
            data: &[20, 51, 0],
        }];
        let bytes = vxz_bytes(&coords, &attr, 4).unwrap_or_default();
        assert_eq!(&bytes[..4], b"VXZ\0");
        let start = u32::from_be_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]) as usize;
        let header: Value = serde_json::from_slice(&bytes[8..start]).unwrap_or_default();
        assert_eq!(header["attr"], json!([["a", 1]]));
        assert_eq!(header["num_voxel"], 3);
        let chunks = header["chunks"].as_array().cloned().unwrap_or_default();
        assert_eq!(chunks.len(), 2);
        assert_eq!(chunks[0]["idx"], json!([0, 0, 0]));
        assert_eq!(chunks[1]["idx"], json!([1, 0, 0]));
        let blob = &bytes[start..];
        let chunk = |c: &Value| {
            let (o, l) = (c["ptr"][0].as_u64(), c["ptr"][1].as_u64());
            let (o, l) = (o.unwrap_or(0) as usize, l.unwrap_or(0) as usize);
            blob[o..o + l].to_vec()
        };
        let first = chunk(&chunks[0]);
        assert_eq!(stream(&first, &chunks[0]["svo"]), vec![0x11, 0x01, 0x01]);
        assert_eq!(stream(&first, &chunks[0]["a"]), vec![0, 20]);
        // (5, 1, 0) is local (1, 1, 0): code 6, child 6 of the root's child 0.
        let second = chunk(&chunks[1]);
        assert_eq!(stream(&second, &chunks[1]["svo"]), vec![0x01, 0x40]);
        assert_eq!(stream(&second, &chunks[1]["a"]), vec![51]);
    }

    #[test]
    fn empty_repeated_and_misshapen_grids_are_refused() {
        let attr = |data: &'static [u8]| Attr {
            name: "a",
            channels: 1,
            data,
        };
        assert!(vxz_bytes(&[], &[], 256).is_err());
        assert!(vxz_bytes(&[[1, 2, 3], [1, 2, 3]], &[attr(&[0, 0])], 256).is_err());
        assert!(vxz_bytes(&[[1, 2, 3]], &[attr(&[0, 0])], 256).is_err());
        assert!(vxz_bytes(&[[1, 2, 3]], &[attr(&[0])], 100).is_err());
    }
}
