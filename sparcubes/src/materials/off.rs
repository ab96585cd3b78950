//! OFF appearance: vertex colours of a `COFF` file (after the coordinates and, with `N`, the
//! normal) and face colours after a face's indices, each as three or four numbers, integers
//! 0–255 or floats 0–1 (Geomview's OFF), taken as sRGB values. A face colour given as one
//! colour-map index is named as not read; faces without a colour keep the vertex colours.

use super::mtl::srgb_to_linear;
use super::{Appearance, NONE};
use crate::error::Result;
use crate::io::parse_err;
use std::path::Path;

/// Linear RGBA from three or four sRGB numbers (0–255 when any is above 1, else 0–1).
fn rgba(v: &[f32]) -> Option<[f32; 4]> {
    if !(3..=4).contains(&v.len()) || v.iter().any(|x| !x.is_finite()) {
        return None;
    }
    let scale = if v.iter().any(|&x| x > 1.0) {
        255.0
    } else {
        1.0
    };
    let c = [v[0], v[1], v[2]].map(|x| srgb_to_linear((x / scale).clamp(0.0, 1.0)));
    let a = v.get(3).map_or(1.0, |a| (a / scale).clamp(0.0, 1.0));
    Some([c[0], c[1], c[2], a])
}

pub(crate) fn read(bytes: &[u8], path: &Path) -> Result<Appearance> {
    let text = String::from_utf8_lossy(bytes);
    let mut lines = text
        .lines()
        .map(|l| l.split('#').next().unwrap_or("").trim())
        .filter(|l| !l.is_empty());
    let header = lines.next().unwrap_or("");
    let mut words = header.split_whitespace();
    let kind = words.next().unwrap_or("");
    let prefix = kind.strip_suffix("OFF").unwrap_or("");
    let (colored, normals) = (prefix.contains('C'), prefix.contains('N'));
    let mut counts: Vec<usize> = words.filter_map(|w| w.parse().ok()).collect();
    if counts.len() < 2 {
        counts = lines
            .next()
            .unwrap_or("")
            .split_whitespace()
            .filter_map(|w| w.parse().ok())
            .collect();
    }
    let (nv, nf) = match counts[..] {
        [nv, nf, ..] => (nv, nf),
        _ => return Err(parse_err(path, "OFF: no vertex and face counts")),
    };
    let mut out = Appearance::default();
    let mut vertex_colors = Vec::new();
    for line in lines.by_ref().take(nv) {
        let v: Vec<f32> = line
            .split_whitespace()
            .map(|w| w.parse().unwrap_or(f32::NAN))
            .collect();
        out.surface
            .positions
            .push([0, 1, 2].map(|k| v.get(k).copied().unwrap_or(f32::NAN)));
        let from = if normals { 6 } else { 3 };
        let c = v.get(from..).unwrap_or(&[]);
        let c = &c[..c.len().min(4)];
        vertex_colors.push(if colored { rgba(c) } else { None });
    }
    for line in lines.take(nf) {
        face(line, nv, &mut out);
    }
    let s = &mut out.surface;
    if let Some(vc) = vertex_colors.into_iter().collect::<Option<Vec<_>>>() {
        if !vc.is_empty() {
            let base = s.color.values.len() as u32;
            s.color.values.extend(vc);
            for t in 0..s.triangles.len() {
                if s.color.corners.get(t).is_none_or(|c| c[0] == NONE) {
                    let corners = s.triangles[t].map(|i| base + i);
                    match s.color.corners.get_mut(t) {
                        Some(c) => *c = corners,
                        None => s.color.push(t, corners),
                    }
                }
            }
        }
    }
    Ok(out)
}

/// One face line: its triangles, and its colour on their corners when it has one.
fn face(line: &str, nv: usize, out: &mut Appearance) {
    let w: Vec<&str> = line.split_whitespace().collect();
    let Some(k) = w.first().and_then(|x| x.parse::<usize>().ok()) else {
        return;
    };
    let Some(idx) = w.get(1..=k).and_then(|ix| {
        ix.iter()
            .map(|x| x.parse::<u32>().ok())
            .collect::<Option<Vec<u32>>>()
    }) else {
        return;
    };
    if idx.iter().any(|&i| i as usize >= nv) {
        return;
    }
    let rest: Vec<f32> = w[k + 1..]
        .iter()
        .map(|x| x.parse().unwrap_or(f32::NAN))
        .collect();
    let color = rgba(&rest);
    if rest.len() == 1 {
        out.facts
            .skip("OFF face colours given as colour-map indices");
    }
    let s = &mut out.surface;
    for j in 1..idx.len().saturating_sub(1) {
        let t = s.triangles.len();
        s.triangles.push([idx[0], idx[j], idx[j + 1]]);
        if let Some(c) = color {
            s.color.values.push(c);
            s.color.push(t, [s.color.values.len() as u32 - 1; 3]);
        }
    }
}
