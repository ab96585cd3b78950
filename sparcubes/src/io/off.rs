//! Object File Format via `off-rs`.
//!
//! `off-rs` accepts only the plain `OFF` header on a line of its own and one colour format, so
//! the text is first put in that form: header variants (`COFF`, `NOFF`, `CNOFF`, `STOFF`, counts
//! on the header line) are accepted, and colours, normals and texture coordinates after the
//! coordinates or face indices are dropped, and so is a face with a bad vertex index (not a
//! number, or not below the vertex count), counted with its line (module docs of [`super`]).
//! Our own cap on the counts comes first; the parser runs with its limits at their maximum.

use super::{bad_face, check_count, parse_err, push_polygon, LoadStats};
use crate::error::Result;
use crate::mesh::TriMesh;
use off_rs::parser::options::{Limits, Options};
use std::path::Path;

pub(crate) fn read(bytes: &[u8], path: &Path, stats: &mut LoadStats) -> Result<TriMesh> {
    let text = std::str::from_utf8(bytes)
        .map_err(|_| parse_err(path, "OFF: not a text file (invalid UTF-8)"))?;
    let canonical = canonicalise(text, stats).map_err(|r| parse_err(path, format!("OFF: {r}")))?;
    let (nv, nf) = canonical.1;
    check_count(path, "vertices", nv)?;
    check_count(path, "faces", nf)?;
    let options = Options {
        limits: Limits::MAX,
        ..Options::default()
    };
    let off =
        off_rs::parse(&canonical.0, options).map_err(|e| parse_err(path, format!("OFF: {e}")))?;

    let mut mesh = TriMesh::new(
        off.vertices
            .iter()
            .map(|v| [v.position.x, v.position.y, v.position.z])
            .collect(),
        Vec::new(),
    );
    let mut poly = Vec::new();
    for f in &off.faces {
        poly.clear();
        poly.extend(
            f.vertices
                .iter()
                .map(|&i| u32::try_from(i).unwrap_or(u32::MAX)),
        );
        push_polygon(&mut mesh.triangles, &poly, stats);
    }
    Ok(mesh)
}

/// Rewrites an OFF text into the form `off-rs` reads; returns it with the declared counts.
fn canonicalise(
    text: &str,
    stats: &mut LoadStats,
) -> std::result::Result<(String, (usize, usize)), String> {
    // (1-based line number, text without comment), blank lines left out.
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(no, l)| (no + 1, l.split('#').next().unwrap_or("").trim()))
        .filter(|(_, l)| !l.is_empty());
    let (_, header) = lines.next().ok_or("empty file")?;
    let mut words = header.split_whitespace();
    let keyword = words.next().unwrap_or("");
    let variant = keyword
        .strip_suffix("OFF")
        .filter(|p| p.chars().all(|c| "STCNH4".contains(c)) && p.len() <= 5)
        .ok_or_else(|| format!("the first line is `{}`, not `OFF`", clip(header)))?;
    if variant.contains('4') {
        return Err(format!("unsupported OFF variant `{keyword}`"));
    }
    // Counts: on the header line, or the next line.
    let rest: Vec<&str> = words.collect();
    let counts_line: Vec<&str> = if rest.is_empty() {
        lines
            .next()
            .ok_or("no counts line")?
            .1
            .split_whitespace()
            .collect()
    } else {
        rest
    };
    let parse = |s: &str| {
        s.parse::<usize>()
            .map_err(|_| format!("bad count `{}`", clip(s)))
    };
    if counts_line.len() < 2 {
        return Err("the counts line needs at least two numbers".to_string());
    }
    let nv = parse(counts_line[0])?;
    let nf = parse(counts_line[1])?;
    let cap = text.len() / 2 + 1;
    if nv > cap || nf > cap {
        return Err(format!(
            "the header claims {nv} vertices and {nf} faces, more than the file can hold \
             (truncated?)"
        ));
    }

    let mut out = String::with_capacity(text.len() + 16);
    for _ in 0..nv {
        let Some((_, l)) = lines.next() else { break };
        let w: Vec<&str> = l.split_whitespace().take(3).collect();
        out.push_str(&w.join(" "));
        out.push('\n');
    }
    let mut kept_faces = nf;
    let mut indices: Vec<&str> = Vec::new();
    for _ in 0..nf {
        let Some((no, l)) = lines.next() else { break };
        let mut w = l.split_whitespace();
        let first = w.next().unwrap_or("");
        let n = first.parse::<usize>().unwrap_or(usize::MAX);
        if n < 3 {
            // Points and segments: off-rs refuses them; count them and leave them out.
            match n {
                1 => stats.points_skipped += 1,
                2 => stats.lines_skipped += 1,
                _ => {}
            }
            kept_faces -= 1;
            continue;
        }
        indices.clear();
        indices.extend(w.take(n));
        if let Some(why) = face_problem(first, n, &indices, nv) {
            bad_face(stats, || format!("OFF line {no}: {why}"));
            kept_faces -= 1;
            continue;
        }
        out.push_str(first);
        for x in &indices {
            out.push(' ');
            out.push_str(x);
        }
        out.push('\n');
    }
    let header = format!("OFF\n{nv} {kept_faces} 0\n");
    out.insert_str(0, &header);
    Ok((out, (nv, nf)))
}

/// What is wrong with an OFF face line (its vertex count word `first`, parsed as `n`, and
/// the index words after it), if anything, for a file of `nv` vertices.
fn face_problem(first: &str, n: usize, indices: &[&str], nv: usize) -> Option<String> {
    if n == usize::MAX {
        return Some(format!(
            "the face's vertex count `{}` is not a number",
            clip(first)
        ));
    }
    if indices.len() < n {
        return Some(format!(
            "the face has {} of its {n} vertex indices",
            indices.len()
        ));
    }
    indices.iter().find_map(|x| match x.parse::<usize>() {
        Ok(i) if i < nv => None,
        Ok(i) => Some(format!(
            "vertex index {i} is out of range (the file has {nv} vertices)"
        )),
        Err(_) => Some(format!("vertex index `{}` is not a valid index", clip(x))),
    })
}

/// The start of a string, for error messages.
fn clip(s: &str) -> String {
    s.chars().take(40).collect()
}
