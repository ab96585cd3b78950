//! Wavefront OBJ via `tobj`.
//!
//! Only geometry is read: the text is first reduced to its `v` and `f` statements (texture and
//! normal indices removed from face corners), so bad texture/normal references, material
//! libraries and object/group splits cannot fail or fragment the load. `p` and `l` statements
//! are counted as skipped points and line segments (tobj would read a three-point `l` as a
//! triangle). Face corners are resolved here (relative indices too) and checked against the
//! file's vertex count: a face with a bad index is dropped and counted (module docs of
//! [`super`]), so tobj only ever sees valid, absolute indices.

use super::{bad_face, check_count, parse_err, push_polygon, LoadStats};
use crate::error::Result;
use crate::mesh::TriMesh;
use std::path::Path;

/// The 1-based absolute index of an OBJ face corner (`7`, `-1`, `7/2/5`) given the vertices
/// defined before it and in the whole file; `Err` says why it is bad.
fn corner(word: &str, before: usize, total: usize) -> std::result::Result<usize, String> {
    let text = word.split('/').next().unwrap_or(word);
    let i: i64 = text
        .parse()
        .map_err(|_| format!("vertex index `{}` is not a number", clip(text)))?;
    let abs = if i < 0 { before as i64 + i + 1 } else { i };
    if abs < 1 || abs as usize > total {
        return Err(format!(
            "vertex index {i} is out of range (the file has {total} vertices)"
        ));
    }
    Ok(abs as usize)
}

fn clip(s: &str) -> String {
    s.chars().take(30).collect()
}

pub(crate) fn read(bytes: &[u8], path: &Path, stats: &mut LoadStats) -> Result<TriMesh> {
    let text = String::from_utf8_lossy(bytes);
    let total = text
        .lines()
        .filter(|l| l.split_whitespace().next() == Some("v"))
        .count();
    let mut geometry = String::with_capacity(text.len().min(1 << 28));
    let (mut n_v, mut n_f) = (0usize, 0usize);
    let mut corners: Vec<usize> = Vec::new();
    for (no, line) in text.lines().enumerate() {
        let line = line.trim();
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                n_v += 1;
                geometry.push_str(line);
                geometry.push('\n');
            }
            Some("f") => {
                n_f += 1;
                corners.clear();
                let mut bad = None;
                for w in words {
                    match corner(w, n_v, total) {
                        Ok(i) => corners.push(i),
                        Err(why) => {
                            bad = Some(why);
                            break;
                        }
                    }
                }
                if let Some(why) = bad {
                    bad_face(stats, || format!("OBJ line {}: {why}", no + 1));
                    continue;
                }
                geometry.push('f');
                for i in &corners {
                    geometry.push(' ');
                    geometry.push_str(&i.to_string());
                }
                geometry.push('\n');
            }
            Some("p") => stats.points_skipped += words.count() as u64,
            Some("l") => stats.lines_skipped += words.count().saturating_sub(1) as u64,
            _ => {}
        }
    }
    if n_v == 0 && n_f == 0 {
        return Err(parse_err(
            path,
            "no vertex (`v`) or face (`f`) statement: not an OBJ file",
        ));
    }
    check_count(path, "vertices", n_v)?;
    check_count(path, "faces", n_f)?;

    let options = tobj::LoadOptions {
        single_index: false,
        triangulate: false,
        ignore_points: false,
        ignore_lines: false,
    };
    let mut reader = std::io::Cursor::new(geometry.as_bytes());
    let (models, _) = tobj::load_obj_buf(&mut reader, &options, |_| {
        Err(tobj::LoadError::MaterialParseError)
    })
    .map_err(|e| parse_err(path, format!("OBJ: {e}")))?;

    // tobj keeps only the vertices a face uses: an empty mesh's message counts the file's.
    stats.vertices_in_file = Some(n_v as u64);
    let mut mesh = TriMesh::default();
    let mut poly: Vec<u32> = Vec::new();
    for model in &models {
        let m = &model.mesh;
        let base = mesh.positions.len() as u32;
        mesh.positions
            .extend(m.positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        if m.face_arities.is_empty() {
            for t in m.indices.chunks_exact(3) {
                mesh.triangles.push([base + t[0], base + t[1], base + t[2]]);
            }
        } else {
            let mut at = 0usize;
            for &arity in &m.face_arities {
                let end = at.saturating_add(arity as usize).min(m.indices.len());
                poly.clear();
                poly.extend(m.indices[at..end].iter().map(|&i| base + i));
                push_polygon(&mut mesh.triangles, &poly, stats);
                at = end;
            }
        }
    }
    Ok(mesh)
}
