//! STL, ascii and binary. Identical corners are welded into shared vertices.
//!
//! Binary files are read with `stl_io`, after checking that the file holds the triangles its
//! header claims. `stl_io` decides between ascii and binary by a `solid ` prefix, which some
//! binary writers also put in their header, so we decide first, by the size a binary file must
//! have. Ascii files are read here: `stl_io` 0.11 stops at the first `endsolid` (files with
//! several solids are common) and refuses a whole file for one NaN facet normal, where we
//! ignore normals and let sanitising drop faces with non-finite corners.

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

/// Why a file of `len` bytes that starts with `head` (at least its first kilobyte, or all of
/// it) has no triangle, when its header alone says so: a binary STL header claiming 0
/// triangles. [`read`] would read such a file as binary (it is not ascii, or it is exactly
/// the header long) and take nothing after the header, so the rest need not be read.
pub(crate) fn empty_by_header(head: &[u8], len: u64) -> Option<String> {
    let binary = len == HEADER as u64 || !looks_ascii(head);
    (claimed(head) == Some(0) && binary).then(|| {
        format!(
            "its binary STL header claims 0 triangles (a file of {len} bytes; nothing after the \
             {HEADER}-byte header is read)"
        )
    })
}

pub(crate) fn read(bytes: &[u8], path: &Path, _stats: &mut LoadStats) -> Result<TriMesh> {
    if !looks_binary(bytes) && looks_ascii(bytes) {
        return read_ascii(bytes, path);
    }
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
    let mut data = bytes[..need].to_vec();
    data[..80].fill(0);

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

/// Reads ascii STL: every `vertex x y z` line, three per facet, over all solids.
fn read_ascii(bytes: &[u8], path: &Path) -> Result<TriMesh> {
    let text = String::from_utf8_lossy(bytes);
    let mut corners: Vec<[f32; 3]> = Vec::new();
    let mut in_facet = 0usize;
    for (no, line) in text.lines().enumerate() {
        let mut w = line.split_whitespace();
        match w.next() {
            Some("vertex") => {
                let mut p = [0f32; 3];
                for c in &mut p {
                    let tok = w.next().ok_or_else(|| {
                        parse_err(path, format!("STL line {}: vertex needs 3 numbers", no + 1))
                    })?;
                    *c = tok.parse().map_err(|_| {
                        parse_err(
                            path,
                            format!(
                                "STL line {}: bad number `{}`",
                                no + 1,
                                tok.chars().take(30).collect::<String>()
                            ),
                        )
                    })?;
                }
                corners.push(p);
                in_facet += 1;
            }
            Some("endfacet") => {
                if in_facet != 3 {
                    return Err(parse_err(
                        path,
                        format!("STL line {}: facet with {in_facet} vertices, not 3", no + 1),
                    ));
                }
                in_facet = 0;
            }
            _ => {}
        }
    }
    if in_facet != 0 {
        return Err(parse_err(path, "STL: ends inside a facet (truncated?)"));
    }
    check_count(path, "triangles", corners.len() / 3)?;
    // Weld by bit pattern, as stl_io does for binary files.
    let mut index = std::collections::HashMap::new();
    let mut positions = Vec::new();
    let mut triangles = Vec::with_capacity(corners.len() / 3);
    for tri in corners.chunks_exact(3) {
        let mut t = [0u32; 3];
        for (slot, p) in t.iter_mut().zip(tri) {
            *slot = *index.entry(p.map(f32::to_bits)).or_insert_with(|| {
                positions.push(*p);
                (positions.len() - 1) as u32
            });
        }
        triangles.push(t);
    }
    Ok(TriMesh::new(positions, triangles))
}
