//! Writing numpy `.npz` files: a ZIP archive of uncompressed (stored) members, one `.npy`
//! file (format version 1.0) per array, as `numpy.savez` writes them. `numpy.load` reads them
//! without any other package.

use crate::error::{Error, Result};

/// One array of an `.npz` file.
#[derive(Debug, Clone)]
pub struct Array {
    /// Member name without `.npy`.
    pub name: String,
    /// numpy type string, e.g. `<f4`, `|u1`, `<U16`.
    pub descr: String,
    /// Shape (empty for a scalar).
    pub shape: Vec<usize>,
    /// The elements' bytes, row-major, little-endian.
    pub data: Vec<u8>,
}

impl Array {
    /// An array of little-endian numbers (`descr` like `<f4`), with `shape`.
    pub fn numbers<T: bytemuck::Pod>(name: &str, descr: &str, shape: Vec<usize>, v: &[T]) -> Self {
        let data = if cfg!(target_endian = "little") {
            bytemuck::cast_slice(v).to_vec()
        } else {
            let width = std::mem::size_of::<T>();
            bytemuck::cast_slice::<T, u8>(v)
                .chunks_exact(width)
                .flat_map(|c| c.iter().rev().copied())
                .collect()
        };
        Self {
            name: name.into(),
            descr: descr.into(),
            shape,
            data,
        }
    }

    /// A 0-d unicode string array (numpy `<U{len}`, UTF-32 little-endian).
    pub fn text(name: &str, value: &str) -> Self {
        let chars: Vec<char> = value.chars().collect();
        let data = chars
            .iter()
            .flat_map(|&c| (c as u32).to_le_bytes())
            .collect();
        Self {
            name: name.into(),
            descr: format!("<U{}", chars.len().max(1)),
            shape: Vec::new(),
            data: if chars.is_empty() { vec![0; 4] } else { data },
        }
    }

    /// The `.npy` bytes of this array.
    fn npy(&self) -> Vec<u8> {
        let shape = match self.shape.len() {
            0 => "()".to_string(),
            1 => format!("({},)", self.shape[0]),
            _ => format!(
                "({})",
                self.shape
                    .iter()
                    .map(|d| d.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        };
        let mut header = format!(
            "{{'descr': '{}', 'fortran_order': False, 'shape': {shape}, }}",
            self.descr
        );
        // Magic (6) + version (2) + length (2) + header, padded with spaces to a multiple of
        // 64 bytes and ended by a newline.
        let unpadded = 10 + header.len() + 1;
        header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
        header.push('\n');
        let mut out = Vec::with_capacity(10 + header.len() + self.data.len());
        out.extend_from_slice(b"\x93NUMPY\x01\x00");
        out.extend_from_slice(&(header.len() as u16).to_le_bytes());
        out.extend_from_slice(header.as_bytes());
        out.extend_from_slice(&self.data);
        out
    }
}

/// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320) of `data`, as ZIP stores it.
fn crc32(data: &[u8]) -> u32 {
    static TABLE: std::sync::OnceLock<[u32; 256]> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        let mut t = [0u32; 256];
        for (i, slot) in t.iter_mut().enumerate() {
            let mut c = i as u32;
            for _ in 0..8 {
                c = if c & 1 == 1 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
            *slot = c;
        }
        t
    });
    let mut c = !0u32;
    for &b in data {
        c = table[((c ^ b as u32) & 0xff) as usize] ^ (c >> 8);
    }
    !c
}

/// The bytes of an `.npz` archive holding `arrays` (stored members, no ZIP64: each member
/// and the archive must stay below 4 GiB).
pub fn npz_bytes(arrays: &[Array]) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut central = Vec::new();
    for a in arrays {
        let npy = a.npy();
        let name = format!("{}.npy", a.name);
        if npy.len() >= u32::MAX as usize || out.len() >= u32::MAX as usize {
            return Err(Error::TooLarge(format!(
                "array {:?} is too large for an .npz without ZIP64",
                a.name
            )));
        }
        let (crc, size, offset) = (crc32(&npy), npy.len() as u32, out.len() as u32);
        // Local file header: version 2.0, no flags, stored, fixed time 1980-01-01 00:00.
        let mut local = Vec::with_capacity(30 + name.len());
        local.extend_from_slice(&0x0403_4b50u32.to_le_bytes());
        local.extend_from_slice(&20u16.to_le_bytes());
        local.extend_from_slice(&0u16.to_le_bytes());
        local.extend_from_slice(&0u16.to_le_bytes());
        local.extend_from_slice(&0u16.to_le_bytes());
        local.extend_from_slice(&0x21u16.to_le_bytes());
        local.extend_from_slice(&crc.to_le_bytes());
        local.extend_from_slice(&size.to_le_bytes());
        local.extend_from_slice(&size.to_le_bytes());
        local.extend_from_slice(&(name.len() as u16).to_le_bytes());
        local.extend_from_slice(&0u16.to_le_bytes());
        local.extend_from_slice(name.as_bytes());
        out.extend_from_slice(&local);
        out.extend_from_slice(&npy);
        // Central directory entry.
        central.extend_from_slice(&0x0201_4b50u32.to_le_bytes());
        central.extend_from_slice(&20u16.to_le_bytes());
        central.extend_from_slice(&local[4..30]);
        central.extend_from_slice(&0u16.to_le_bytes()); // comment length
        central.extend_from_slice(&0u16.to_le_bytes()); // disk number
        central.extend_from_slice(&0u16.to_le_bytes()); // internal attributes
        central.extend_from_slice(&0u32.to_le_bytes()); // external attributes
        central.extend_from_slice(&offset.to_le_bytes());
        central.extend_from_slice(name.as_bytes());
    }
    if out.len() + central.len() >= u32::MAX as usize {
        return Err(Error::TooLarge("the .npz would exceed 4 GiB".into()));
    }
    let (cd_offset, cd_size) = (out.len() as u32, central.len() as u32);
    out.extend_from_slice(&central);
    out.extend_from_slice(&0x0605_4b50u32.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    out.extend_from_slice(&(arrays.len() as u16).to_le_bytes());
    out.extend_from_slice(&(arrays.len() as u16).to_le_bytes());
    out.extend_from_slice(&cd_size.to_le_bytes());
    out.extend_from_slice(&cd_offset.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_and_npy_header_follow_the_formats() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        let a = Array::numbers("x", "<f4", vec![2, 3], &[0f32; 6]);
        let npy = a.npy();
        let len = u16::from_le_bytes([npy[8], npy[9]]) as usize;
        assert_eq!((10 + len) % 64, 0);
        let header = String::from_utf8_lossy(&npy[10..10 + len]);
        assert!(header.starts_with("{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }"));
        assert!(header.ends_with('\n'));
        assert_eq!(npy.len(), 10 + len + 24);
        let bytes = npz_bytes(&[a, Array::text("frame", "source")]).unwrap_or_default();
        assert_eq!(&bytes[..4], b"PK\x03\x04");
        assert_eq!(&bytes[bytes.len() - 22..bytes.len() - 18], b"PK\x05\x06");
    }
}
