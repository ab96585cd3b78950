//! Tensor encodings: a tensor is a zstd-compressed blob of its elements' little-endian bytes
//! laid out in byte planes, with its dtype (numpy notation: `<u1`, `<u2`, `<u4`, `<f2`, `<f4`) and shape
//! stored beside it. For shape `[n, k]` (`[n]` is `k = 1`) and `w`-byte scalars the blob holds
//! `k·w` planes of `n` bytes, column by column and within a column from the least significant
//! byte up: byte `b` of element `(i, j)` is at `(j·w + b)·n + i`. Grouping the bytes of one
//! column and significance together is what zstd compresses best (docs/PERFORMANCE.md: coords
//! 6×, cells 5×, sdf 1.2× smaller than row-major bytes, and faster to compress); in numpy,
//! `np.frombuffer(raw, np.uint8).reshape(k, w, n).transpose(2, 0, 1).copy().view(dtype)`
//! undoes it (docs/FORMAT.md).
//!
//! Every frame carries zstd's content checksum (schema version 3): a decoder (ours,
//! pyarrow's `pa.decompress`, `zstandard`) verifies it and fails on a damaged blob instead of
//! returning wrong numbers, and ours refuses a frame without one.

use crate::error::{Result, SchemaError};
use serde::{Deserialize, Serialize};

/// Element type of a tensor, named as numpy names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum DType {
    /// Unsigned 8-bit integer (`<u1`).
    U8,
    /// Little-endian unsigned 16-bit integer (`<u2`).
    U16,
    /// Little-endian unsigned 32-bit integer (`<u4`).
    U32,
    /// Little-endian IEEE 754 half precision (`<f2`).
    F16,
    /// Little-endian IEEE 754 single precision (`<f4`).
    F32,
}

impl DType {
    /// The numpy dtype string stored in the `*_dtype` column.
    pub fn as_str(self) -> &'static str {
        match self {
            DType::U8 => "<u1",
            DType::U16 => "<u2",
            DType::U32 => "<u4",
            DType::F16 => "<f2",
            DType::F32 => "<f4",
        }
    }

    /// Parses a stored dtype string.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "<u1" | "|u1" => Ok(DType::U8),
            "<f2" => Ok(DType::F16),
            "<u2" => Ok(DType::U16),
            "<u4" => Ok(DType::U32),
            "<f4" => Ok(DType::F32),
            other => Err(SchemaError::Invalid {
                what: "dtype",
                value: other.to_string(),
            }),
        }
    }

    /// Bytes per element.
    pub fn size(self) -> usize {
        match self {
            DType::U8 => 1,
            DType::U16 | DType::F16 => 2,
            DType::U32 | DType::F32 => 4,
        }
    }
}

/// One encoded tensor as stored in a row: dtype, shape and the zstd-compressed bytes. The
/// serde form leaves the blob out (it travels beside the JSON, see `sparc3d-workers`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct EncodedTensor {
    /// Element type.
    pub dtype: DType,
    /// Shape, row-major (`[n, 3]` for coordinates, `[n]` for the SDF).
    pub shape: Vec<u64>,
    /// zstd frame of the element bytes in byte planes (module docs).
    #[serde(skip)]
    pub blob: Vec<u8>,
}

fn compress(raw: &[u8], level: i32) -> Result<Vec<u8>> {
    let mut c = zstd::bulk::Compressor::new(level).map_err(SchemaError::Zstd)?;
    c.include_checksum(true).map_err(SchemaError::Zstd)?;
    c.compress(raw).map_err(SchemaError::Zstd)
}

/// The zstd frame magic number, as stored (little-endian).
const ZSTD_MAGIC: [u8; 4] = [0x28, 0xb5, 0x2f, 0xfd];

/// Whether a zstd frame declares a content checksum (bit 2 of its frame header descriptor,
/// RFC 8878 §3.1.1.1.1).
fn has_checksum(blob: &[u8]) -> bool {
    blob.len() > 4 && blob[..4] == ZSTD_MAGIC && blob[4] & 0x04 != 0
}

/// Elements per tile of the byte-plane shuffles: a tile's element bytes (at most 16 bytes an
/// element) stay in the L1 cache while each plane's run of it is read or written, where a
/// whole-tensor pass per plane went through the cache once for every byte of an element.
const TILE: usize = 2048;

/// Row-major little-endian element bytes (`cols` columns of `width`-byte scalars) regrouped
/// into byte planes: byte `b` of element `(i, j)` goes to `(j·width + b)·n + i`.
fn to_planes(bytes: &[u8], cols: usize, width: usize) -> Vec<u8> {
    let stride = cols * width;
    let n = bytes.len() / stride.max(1);
    let mut out = vec![0u8; n * stride];
    for start in (0..n).step_by(TILE) {
        let end = (start + TILE).min(n);
        let rows = &bytes[start * stride..end * stride];
        for p in 0..stride {
            let plane = &mut out[p * n + start..p * n + end];
            for (o, row) in plane.iter_mut().zip(rows.chunks_exact(stride)) {
                *o = row[p];
            }
        }
    }
    out
}

/// The inverse of [`to_planes`]: byte planes back to row-major element bytes.
fn from_planes(planes: &[u8], cols: usize, width: usize) -> Vec<u8> {
    let stride = cols * width;
    let n = planes.len() / stride.max(1);
    let mut out = vec![0u8; n * stride];
    for start in (0..n).step_by(TILE) {
        let end = (start + TILE).min(n);
        let rows = &mut out[start * stride..end * stride];
        for p in 0..stride {
            let plane = &planes[p * n + start..p * n + end];
            for (row, &b) in rows.chunks_exact_mut(stride).zip(plane) {
                row[p] = b;
            }
        }
    }
    out
}

/// The little-endian bytes of a slice of numbers whose scalars are `width` bytes wide: the
/// slice itself on little-endian hosts (no copy), a byte-swapped copy elsewhere.
fn le_bytes<T: bytemuck::Pod>(v: &[T], width: usize) -> std::borrow::Cow<'_, [u8]> {
    let bytes: &[u8] = bytemuck::cast_slice(v);
    if cfg!(target_endian = "little") {
        std::borrow::Cow::Borrowed(bytes)
    } else {
        std::borrow::Cow::Owned(
            bytes
                .chunks_exact(width)
                .flat_map(|c| c.iter().rev().copied())
                .collect(),
        )
    }
}

impl EncodedTensor {
    /// Encodes the numbers `flat` (row-major scalars of `dtype`) as a tensor of `shape`
    /// (`[n]` or `[n, k]`), in byte planes.
    fn encode<T: bytemuck::Pod>(
        flat: &[T],
        dtype: DType,
        shape: Vec<u64>,
        level: i32,
    ) -> Result<Self> {
        let cols = shape.get(1).copied().unwrap_or(1) as usize;
        let width = dtype.size();
        let raw = to_planes(&le_bytes(flat, width), cols, width);
        Ok(Self {
            dtype,
            shape,
            blob: compress(&raw, level)?,
        })
    }

    /// Encodes `n × 3` unsigned 16-bit integers.
    pub fn from_u16x3(v: &[[u16; 3]], level: i32) -> Result<Self> {
        Self::encode(v.as_flattened(), DType::U16, vec![v.len() as u64, 3], level)
    }

    /// Encodes `n × 3` unsigned 32-bit integers.
    pub fn from_u32x3(v: &[[u32; 3]], level: i32) -> Result<Self> {
        Self::encode(v.as_flattened(), DType::U32, vec![v.len() as u64, 3], level)
    }

    /// Encodes `n × 3` floats.
    pub fn from_f32x3(v: &[[f32; 3]], level: i32) -> Result<Self> {
        Self::encode(v.as_flattened(), DType::F32, vec![v.len() as u64, 3], level)
    }

    /// Encodes `n` floats.
    pub fn from_f32(v: &[f32], level: i32) -> Result<Self> {
        Self::encode(v, DType::F32, vec![v.len() as u64], level)
    }

    /// Encodes floats as `dtype` (`F32` or `F16`, rounded to nearest) with `shape` (`[n]` or
    /// `[n, k]`, row-major over `values`).
    pub fn from_floats(values: &[f32], shape: Vec<u64>, dtype: DType, level: i32) -> Result<Self> {
        let cols = shape.get(1).copied().unwrap_or(1) as usize;
        if shape.iter().product::<u64>() as usize != values.len() || cols == 0 {
            return Err(SchemaError::Tensor {
                name: "floats".into(),
                reason: format!("{} values do not fill shape {shape:?}", values.len()),
            });
        }
        match dtype {
            DType::F32 => Self::encode(values, dtype, shape, level),
            DType::F16 => {
                let halves: Vec<u16> = values
                    .iter()
                    .map(|&v| half::f16::from_f32(v).to_bits())
                    .collect();
                Self::encode(&halves, dtype, shape, level)
            }
            other => Err(SchemaError::Invalid {
                what: "float dtype",
                value: other.as_str().into(),
            }),
        }
    }

    /// Encodes `n` bytes (`<u1`).
    pub fn from_u8(v: &[u8], level: i32) -> Result<Self> {
        Ok(Self {
            dtype: DType::U8,
            shape: vec![v.len() as u64],
            blob: compress(v, level)?,
        })
    }

    /// Decodes a float tensor (`<f2` or `<f4`) into row-major `f32` values.
    pub fn to_floats(&self, name: &str) -> Result<Vec<f32>> {
        let raw = self.raw_bytes(name)?;
        match self.dtype {
            DType::F32 => Ok(scalars(&raw, f32::from_le_bytes)),
            DType::F16 => Ok(scalars(&raw, |c: [u8; 2]| {
                half::f16::from_bits(u16::from_le_bytes(c)).to_f32()
            })),
            other => Err(SchemaError::Tensor {
                name: name.to_string(),
                reason: format!("expected <f2 or <f4, found {}", other.as_str()),
            }),
        }
    }

    /// Encodes `n × 3` bytes (in three byte planes, as the wider tensors).
    pub fn from_u8x3(v: &[[u8; 3]], level: i32) -> Result<Self> {
        Self::encode(v.as_flattened(), DType::U8, vec![v.len() as u64, 3], level)
    }

    /// Decodes an `n × 3` `<u1` tensor.
    pub fn to_u8x3(&self, name: &str) -> Result<Vec<[u8; 3]>> {
        self.to_rows3(name, DType::U8, u8::from_le_bytes)
    }

    /// Decodes an `n` `<u1` tensor.
    pub fn to_u8(&self, name: &str) -> Result<Vec<u8>> {
        self.check(name, DType::U8, None)?;
        self.raw_bytes(name)
    }

    /// Number of elements the shape describes.
    pub fn elements(&self) -> u64 {
        self.shape.iter().product()
    }

    /// Decompresses the blob, checks its length against dtype and shape, and returns the
    /// elements' little-endian bytes in row-major order.
    pub fn raw_bytes(&self, name: &str) -> Result<Vec<u8>> {
        if !has_checksum(&self.blob) {
            return Err(SchemaError::Tensor {
                name: name.to_string(),
                reason: "the blob is not a zstd frame with a content checksum (damaged, or \
                         not written by schema version 3)"
                    .into(),
            });
        }
        let expected = self.elements() as usize * self.dtype.size();
        let raw = zstd::bulk::decompress(&self.blob, expected.max(1)).map_err(|e| {
            SchemaError::Tensor {
                name: name.to_string(),
                reason: format!("zstd: {e}"),
            }
        })?;
        if raw.len() != expected {
            return Err(SchemaError::Tensor {
                name: name.to_string(),
                reason: format!(
                    "{} bytes after decompression, shape {:?} of {} needs {expected}",
                    raw.len(),
                    self.shape,
                    self.dtype.as_str()
                ),
            });
        }
        let cols = self.shape.get(1).copied().unwrap_or(1) as usize;
        Ok(from_planes(&raw, cols, self.dtype.size()))
    }

    fn check(&self, name: &str, dtype: DType, cols: Option<u64>) -> Result<()> {
        let shape_ok = match cols {
            Some(c) => self.shape.len() == 2 && self.shape[1] == c,
            None => self.shape.len() == 1,
        };
        if self.dtype != dtype || !shape_ok {
            return Err(SchemaError::Tensor {
                name: name.to_string(),
                reason: format!(
                    "expected {} with {} columns, found {} shape {:?}",
                    dtype.as_str(),
                    cols.unwrap_or(1),
                    self.dtype.as_str(),
                    self.shape
                ),
            });
        }
        Ok(())
    }

    /// Decodes an `n × 3` tensor of `dtype`, each scalar read from its `W` little-endian
    /// bytes by `from_le`.
    fn to_rows3<T, const W: usize>(
        &self,
        name: &str,
        dtype: DType,
        from_le: fn([u8; W]) -> T,
    ) -> Result<Vec<[T; 3]>> {
        self.check(name, dtype, Some(3))?;
        let raw = self.raw_bytes(name)?;
        Ok(raw
            .chunks_exact(3 * W)
            .map(|row| std::array::from_fn(|j| from_le(std::array::from_fn(|b| row[j * W + b]))))
            .collect())
    }

    /// Decodes an `n × 3` `<u2` tensor.
    pub fn to_u16x3(&self, name: &str) -> Result<Vec<[u16; 3]>> {
        self.to_rows3(name, DType::U16, u16::from_le_bytes)
    }

    /// Decodes an `n × 3` `<u4` tensor.
    pub fn to_u32x3(&self, name: &str) -> Result<Vec<[u32; 3]>> {
        self.to_rows3(name, DType::U32, u32::from_le_bytes)
    }

    /// Decodes an `n × 3` `<f4` tensor.
    pub fn to_f32x3(&self, name: &str) -> Result<Vec<[f32; 3]>> {
        self.to_rows3(name, DType::F32, f32::from_le_bytes)
    }

    /// Decodes an `n` `<f4` tensor.
    pub fn to_f32(&self, name: &str) -> Result<Vec<f32>> {
        self.check(name, DType::F32, None)?;
        let raw = self.raw_bytes(name)?;
        Ok(scalars(&raw, f32::from_le_bytes))
    }
}

/// The scalars of the little-endian bytes `raw`, each read from its `W` bytes by `from_le`.
fn scalars<T, const W: usize>(raw: &[u8], from_le: fn([u8; W]) -> T) -> Vec<T> {
    raw.chunks_exact(W)
        .map(|c| from_le(std::array::from_fn(|b| c[b])))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_every_dtype() -> Result<()> {
        let c = vec![[1u16, 2, 3], [65535, 0, 7]];
        let t = EncodedTensor::from_u16x3(&c, 3)?;
        assert_eq!(t.shape, vec![2, 3]);
        assert_eq!(t.to_u16x3("c")?, c);
        let f = vec![0.5f32, -1.25, f32::MAX];
        assert_eq!(EncodedTensor::from_f32(&f, 3)?.to_f32("f")?, f);
        let d = vec![[0.1f32, -0.2, 0.3]];
        assert_eq!(EncodedTensor::from_f32x3(&d, 3)?.to_f32x3("d")?, d);
        let u = vec![[1u32, 2, 4_000_000_000]];
        assert_eq!(EncodedTensor::from_u32x3(&u, 3)?.to_u32x3("u")?, u);
        let e = EncodedTensor::from_f32(&[], 3)?;
        assert!(e.to_f32("e")?.is_empty());
        let h = EncodedTensor::from_floats(
            &[0.5, -1.25, 3.0e-8, 1.0, 2.0, 4.0],
            vec![2, 3],
            DType::F16,
            3,
        )?;
        assert_eq!(h.dtype.as_str(), "<f2");
        let back = h.to_floats("h")?;
        assert_eq!(back[..2], [0.5, -1.25]);
        assert_eq!(back[2], half::f16::from_f32(3.0e-8).to_f32());
        assert!(EncodedTensor::from_floats(&[1.0], vec![2], DType::F16, 3).is_err());
        let o = EncodedTensor::from_u8(&[0, 1, 1], 3)?;
        assert_eq!(o.to_u8("o")?, vec![0, 1, 1]);
        // Sample tensors are framed like the others: with zstd's content checksum.
        assert!(has_checksum(&h.blob) && has_checksum(&o.blob));
        Ok(())
    }

    #[test]
    fn plane_shuffles_match_their_definition_across_tiles() {
        // Several tiles and a partial one, for every element stride the tensors use.
        let n = 2 * TILE + 77;
        for stride in [1, 2, 4, 6, 12] {
            let bytes: Vec<u8> = (0..n * stride).map(|k| (k * 31 % 251) as u8).collect();
            let planes = to_planes(&bytes, stride, 1);
            for i in (0..n).step_by(97) {
                for b in 0..stride {
                    assert_eq!(planes[b * n + i], bytes[i * stride + b], "{stride} {i} {b}");
                }
            }
            assert_eq!(from_planes(&planes, stride, 1), bytes, "stride {stride}");
        }
    }

    #[test]
    fn little_endian_on_disk() -> Result<()> {
        let t = EncodedTensor::from_u16x3(&[[0x0102, 0x0304, 0x0506]], 1)?;
        assert_eq!(t.raw_bytes("t")?, vec![2, 1, 4, 3, 6, 5]);
        Ok(())
    }

    #[test]
    fn blob_holds_byte_planes_column_by_column() -> Result<()> {
        let t =
            EncodedTensor::from_u16x3(&[[0x0102, 0x0304, 0x0506], [0x0a0b, 0x0c0d, 0x0e0f]], 1)?;
        assert!(has_checksum(&t.blob));
        let stored = zstd::bulk::decompress(&t.blob, 64).map_err(SchemaError::Zstd)?;
        // x low bytes, x high bytes, y low, y high, z low, z high.
        assert_eq!(
            stored,
            vec![2, 0x0b, 1, 0x0a, 4, 0x0d, 3, 0x0c, 6, 0x0f, 5, 0x0e]
        );
        let f = EncodedTensor::from_f32(&[1.0, -2.5], 1)?;
        let stored = zstd::bulk::decompress(&f.blob, 64).map_err(SchemaError::Zstd)?;
        let (a, b) = (1.0f32.to_le_bytes(), (-2.5f32).to_le_bytes());
        assert_eq!(stored, vec![a[0], b[0], a[1], b[1], a[2], b[2], a[3], b[3]]);
        assert_eq!(f.to_f32("f")?, vec![1.0, -2.5]);
        Ok(())
    }

    /// Issue 10, item 2: a damaged blob never decodes to wrong numbers: a flipped bit
    /// anywhere fails loudly, or (in the few bits zstd does not use) decodes to exactly the
    /// stored tensor.
    #[test]
    fn a_flipped_bit_of_a_blob_never_decodes_to_wrong_numbers() -> Result<()> {
        let sdf: Vec<f32> = (0..2000).map(|i| (i as f32 * 0.37).sin()).collect();
        let t = EncodedTensor::from_f32(&sdf, 3)?;
        assert_eq!(t.to_f32("sdf")?, sdf);
        let (mut tried, mut refused) = (0, 0);
        for at in 0..t.blob.len() {
            for bit in [0x01u8, 0x10, 0x80] {
                let mut bad = t.clone();
                bad.blob[at] ^= bit;
                tried += 1;
                match bad.to_f32("sdf") {
                    Err(_) => refused += 1,
                    Ok(v) => assert!(v == sdf, "byte {at} flipped by {bit:#x}: wrong numbers"),
                }
            }
        }
        assert!(
            refused * 100 > tried * 99,
            "{refused} of {tried} flips refused"
        );
        // A frame without a checksum (as schema 2 wrote them) is refused.
        let plain = EncodedTensor {
            blob: zstd::bulk::compress(&to_planes(&le_bytes(&sdf, 4), 1, 4), 3)
                .map_err(SchemaError::Zstd)?,
            ..t
        };
        assert!(plain.to_f32("sdf").is_err());
        Ok(())
    }

    #[test]
    fn wrong_shape_or_length_is_an_error() -> Result<()> {
        let mut t = EncodedTensor::from_f32(&[1.0, 2.0], 3)?;
        assert!(t.to_u16x3("t").is_err());
        t.shape = vec![3];
        assert!(t.to_f32("t").is_err());
        t.blob = vec![1, 2, 3];
        assert!(t.to_f32("t").is_err());
        Ok(())
    }
}
