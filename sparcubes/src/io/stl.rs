//! STL (ascii and binary) via `stl_io`, which welds identical corners into shared vertices.
//!
//! `stl_io` decides between ascii and binary by a `solid ` prefix, which some binary writers
//! also put in their header; we decide first by the size a binary file must have, check that a
//! binary file is not truncated before reading it, and hand `stl_io` bytes it reads the right
//! way.

use super::{check_count, parse_err, LoadStats};
use crate::error::Result;
use crate::mesh::TriMesh;
use std::path::Path;

const HEADER: usize = 84;
const RECORD: usize = 50;

/// The triangle count a binary STL header claims, if the file is long enough to have one.
fn claimed(bytes: &[u8]) -> Option<usize> {
    let c = bytes.get(80..84)?;
    Some(u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as usize)
}

/// Whether the bytes have exactly the size of a binary STL with the count its header claims.
pub(crate) fn looks_binary(bytes: &[u8]) -> bool {
    claimed(bytes).is_some_and(|n| {
        n.checked_mul(RECORD)
            .and_then(|b| b.checked_add(HEADER))
            .is_some_and(|len| len == bytes.len())
    })
}

/// Whether the text starts like an ascii STL (`solid`, then a facet or the end).
fn looks_ascii(bytes: &[u8]) -> bool {
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(1024)]);
    let t = head.trim_start();
    t.starts_with("solid") && (t.contains("facet") || t.contains("endsolid"))
}

pub(crate) fn read(bytes: &[u8], path: &Path, _stats: &mut LoadStats) -> Result<TriMesh> {
    let mut data: Vec<u8>;
    if !looks_binary(bytes) && looks_ascii(bytes) {
        // stl_io wants the first line to start with exactly "solid ".
        let start = bytes
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .unwrap_or(0);
        let body = &bytes[start + "solid".len()..];
        data = Vec::with_capacity(bytes.len() + 1);
        data.extend_from_slice(b"solid ");
        data.extend_from_slice(body);
    } else {
        let n = claimed(bytes).ok_or_else(|| {
            parse_err(
                path,
                format!(
                    "STL: {} bytes is too short for a binary STL (84-byte header) and it is not \
                     ascii STL",
                    bytes.len()
                ),
            )
        })?;
        let need = n
            .checked_mul(RECORD)
            .and_then(|b| b.checked_add(HEADER))
            .unwrap_or(usize::MAX);
        if bytes.len() < need {
            return Err(parse_err(
                path,
                format!(
                    "STL: binary header claims {n} triangles ({need} bytes) but the file has {} \
                     bytes (truncated, or not an STL file)",
                    bytes.len()
                ),
            ));
        }
        check_count(path, "triangles", n)?;
        // Blank the 80-byte comment so stl_io never mistakes it for ascii.
        data = bytes[..need].to_vec();
        data[..80].fill(0);
    }

    let mut cursor = std::io::Cursor::new(data);
    let indexed =
        stl_io::read_stl(&mut cursor).map_err(|e| parse_err(path, format!("STL: {e}")))?;
    check_count(path, "vertices", indexed.vertices.len())?;
    let positions = indexed.vertices.iter().map(|v| v.0).collect();
    let triangles = indexed
        .faces
        .iter()
        .map(|f| f.vertices.map(|i| u32::try_from(i).unwrap_or(u32::MAX)))
        .collect();
    Ok(TriMesh::new(positions, triangles))
}
