//! OBJ appearance: faces with their `vt` texture coordinates and `usemtl` materials, vertex
//! colours written as `v x y z r g b` (a common extension, sRGB values in [0, 1]), and the
//! materials of the `mtllib` libraries beside the file ([`super::mtl`]).
//!
//! Faces are triangulated as fans, as the shape's reader does; a corner with a bad vertex
//! index drops its face (the shape's reader counted it), a bad texture index drops the face's
//! coordinates only. A library or map that cannot be read is named in the facts and its
//! materials or textures are left out.

use super::mtl::{self, MtlMaterial, Slot};
use super::{sibling, Appearance, Facts, Image, TextureBudget, NONE};
use crate::error::Result;
use crate::io::Buffers;
use std::collections::HashMap;
use std::path::Path;

/// A 1-based (or negative, relative) OBJ index resolved against `count` elements so far.
fn resolve(word: &str, count: usize) -> Option<u32> {
    let i: i64 = word.parse().ok()?;
    let abs = if i < 0 { count as i64 + i } else { i - 1 };
    (abs >= 0 && (abs as usize) < count).then_some(abs as u32)
}

/// What the statements of an OBJ file build up.
#[derive(Default)]
struct Parse {
    out: Appearance,
    /// Colour per position (sRGB decoded to linear), when that position's line had one.
    colors: Vec<Option<[f32; 4]>>,
    /// Material libraries named, in order.
    libraries: Vec<String>,
    /// Material name of each triangle.
    names: Vec<u32>,
    /// The distinct `usemtl` names.
    used: Vec<String>,
    current: u32,
}

impl Parse {
    fn vertex(&mut self, rest: &[&str]) {
        let v: Vec<f32> = rest.iter().map_while(|w| w.parse().ok()).collect();
        let p = [0, 1, 2].map(|k| v.get(k).copied().unwrap_or(f32::NAN));
        self.out.surface.positions.push(p);
        self.colors.push(match v.len() {
            6 | 7 => {
                let c = [v[3], v[4], v[5]].map(|c| mtl::srgb_to_linear(c.clamp(0.0, 1.0)));
                Some([c[0], c[1], c[2], 1.0])
            }
            _ => None,
        });
    }

    fn face(&mut self, rest: &[&str]) {
        let (nv, nt) = (
            self.out.surface.positions.len(),
            self.out.surface.uv[0].values.len(),
        );
        let mut corners: Vec<(u32, u32)> = Vec::with_capacity(rest.len());
        for w in rest {
            let mut parts = w.split('/');
            let Some(v) = parts.next().and_then(|p| resolve(p, nv)) else {
                return;
            };
            let t = parts.next().and_then(|p| resolve(p, nt)).unwrap_or(NONE);
            corners.push((v, t));
        }
        for k in 1..corners.len().saturating_sub(1) {
            let tri = [corners[0], corners[k], corners[k + 1]];
            let s = &mut self.out.surface;
            let t = s.triangles.len();
            s.triangles.push(tri.map(|c| c.0));
            self.names.push(self.current);
            if tri.iter().all(|c| c.1 != NONE) {
                s.uv[0].push(t, tri.map(|c| c.1));
            }
        }
    }

    fn statement(&mut self, key: &str, rest: &[&str]) {
        match key {
            "v" => self.vertex(rest),
            "vt" => {
                let u = rest.first().and_then(|w| w.parse().ok()).unwrap_or(0.0);
                let v = rest.get(1).and_then(|w| w.parse().ok()).unwrap_or(0.0);
                self.out.surface.uv[0].values.push([u, v]);
            }
            "f" => self.face(rest),
            "usemtl" => {
                let name = rest.join(" ");
                self.current = match self.used.iter().position(|n| *n == name) {
                    Some(i) => i as u32,
                    None => {
                        self.used.push(name);
                        self.used.len() as u32 - 1
                    }
                };
            }
            "mtllib" => self.libraries.push(rest.join(" ")),
            _ => {}
        }
    }
}

pub(crate) fn read(
    bytes: &[u8],
    path: &Path,
    buffers: Buffers,
    budget: TextureBudget,
) -> Result<Appearance> {
    let text = String::from_utf8_lossy(bytes);
    let mut p = Parse {
        current: NONE,
        ..Default::default()
    };
    for line in text.lines() {
        let mut words = line.split_whitespace();
        if let Some(key) = words.next() {
            let rest: Vec<&str> = words.collect();
            p.statement(key, &rest);
        }
    }
    vertex_colors(&mut p);
    let library = libraries(&p.libraries, path, buffers, &mut p.out.facts);
    bind_materials(&mut p, library, path, buffers, budget);
    Ok(p.out)
}

/// Sets the surface's colour channel from the `v` lines' colours, when every vertex has one.
fn vertex_colors(p: &mut Parse) {
    let Some(colors) = p.colors.iter().copied().collect::<Option<Vec<_>>>() else {
        return;
    };
    if colors.is_empty() {
        return;
    }
    let s = &mut p.out.surface;
    s.color.values = colors;
    s.color.corners = s.triangles.clone();
}

/// The materials of every library, in order (the first of a repeated name wins).
fn libraries(
    names: &[String],
    path: &Path,
    buffers: Buffers,
    facts: &mut Facts,
) -> Vec<MtlMaterial> {
    let mut out: Vec<MtlMaterial> = Vec::new();
    for name in names {
        match sibling::read(name, path, buffers) {
            Ok(bytes) => {
                for m in mtl::parse(&String::from_utf8_lossy(&bytes), facts) {
                    if !out.iter().any(|o| o.material.name == m.material.name) {
                        out.push(m);
                    }
                }
            }
            Err(why) => facts.skip(format!("material library `{}`: {why}", sibling::clip(name))),
        }
    }
    out
}

/// Gives every triangle its material (the default one where `usemtl` named none or one the
/// libraries lack), decoding each map's image once, within the `budget`; `path` and `buffers`
/// locate the map files.
fn bind_materials(
    p: &mut Parse,
    library: Vec<MtlMaterial>,
    path: &Path,
    buffers: Buffers,
    mut budget: TextureBudget,
) {
    let mut images: HashMap<String, Option<usize>> = HashMap::new();
    let mut index_of: Vec<u32> = Vec::with_capacity(p.used.len());
    for name in &p.used {
        let Some(m) = library.iter().find(|m| m.material.name == *name) else {
            if !p.libraries.is_empty() {
                p.out.facts.skip(format!(
                    "material `{}`: not defined in the material libraries",
                    sibling::clip(name)
                ));
            }
            index_of.push(NONE);
            continue;
        };
        let mut material = m.material.clone();
        for (slot, spec) in &m.maps {
            let image = *images
                .entry(spec.file.clone())
                .or_insert_with(|| load(&spec.file, path, buffers, &mut budget, &mut p.out));
            let Some(image) = image else { continue };
            match slot {
                Slot::BaseColor => material.base_color_map = Some(spec.bind(image)),
                Slot::Roughness => material.roughness_map = Some(mtl::scalar(spec, image, 0)),
                Slot::Metallic => material.metallic_map = Some(mtl::scalar(spec, image, 0)),
                Slot::Alpha => {
                    let channel = if has_alpha(&p.out.images[image]) {
                        3
                    } else {
                        0
                    };
                    material.alpha_map = Some(mtl::scalar(spec, image, channel));
                }
            }
        }
        index_of.push(p.out.materials.len() as u32);
        p.out.materials.push(material);
    }
    let default = p.out.materials.len() as u32;
    p.out.surface.material = p
        .names
        .iter()
        .map(|&n| match index_of.get(n as usize) {
            Some(&i) if i != NONE => i,
            _ => default,
        })
        .collect();
}

/// Whether an image has any pixel that is not opaque (`map_d` then reads its alpha, else its
/// first channel: grey opacity maps and RGBA images are both written as `map_d`).
fn has_alpha(image: &Option<Image>) -> bool {
    image
        .as_ref()
        .is_some_and(|im| im.pixels.iter().any(|p| p[3] != 255))
}

/// Reads and decodes the map file `name` into the appearance's images; `None` (and named in
/// the facts) when it cannot be, or when it does not fit in what is left of the `budget`.
fn load(
    name: &str,
    path: &Path,
    buffers: Buffers,
    budget: &mut TextureBudget,
    out: &mut Appearance,
) -> Option<usize> {
    let decoded = sibling::read_image(name, path, buffers).and_then(|b| budget.decode(&b));
    match decoded {
        Ok(image) => {
            out.images.push(Some(image));
            Some(out.images.len() - 1)
        }
        Err(why) => {
            out.facts
                .skip(format!("texture `{}`: {why}", sibling::clip(name)));
            None
        }
    }
}
