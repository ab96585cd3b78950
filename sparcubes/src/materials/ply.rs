//! PLY appearance: vertex colours (`red`, `green`, `blue`, optional `alpha`; also the
//! `diffuse_` names), as bytes (0–255) or floats (0–1), taken as sRGB values; and face colours
//! the same way, given to the face's three corners. Texture coordinates with a
//! `comment TextureFile` image are named as not read.

use super::mtl::srgb_to_linear;
use super::{Appearance, NONE};
use crate::error::Result;
use crate::io::parse_err;
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{Property, PropertyAccess, PropertyAccessResult};
use std::path::Path;

/// One vertex or face: position, colour channels found, face indices.
#[derive(Debug, Default)]
struct Elem {
    xyz: [f32; 3],
    rgba: [Option<f32>; 4],
    indices: Vec<u32>,
}

/// A colour property's value in [0, 1] (bytes and shorts scaled by their range).
fn unit(p: &Property) -> Option<f32> {
    Some(match *p {
        Property::UChar(v) => v as f32 / 255.0,
        Property::Char(v) => v.max(0) as f32 / 127.0,
        Property::UShort(v) => v as f32 / 65535.0,
        Property::Float(v) => v,
        Property::Double(v) => v as f32,
        _ => return None,
    })
}

impl PropertyAccess for Elem {
    fn new() -> Self {
        Elem::default()
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        let name = name.strip_prefix("diffuse_").unwrap_or(name);
        let slot = match name {
            "x" | "y" | "z" => {
                let a = (name.as_bytes()[0] - b'x') as usize;
                self.xyz[a] = property.to_f32_lossy().unwrap_or(f32::NAN);
                return PropertyAccessResult::Set;
            }
            "red" | "r" => 0,
            "green" | "g" => 1,
            "blue" | "b" => 2,
            "alpha" | "a" => 3,
            "vertex_indices" | "vertex_index" => {
                self.indices = match property {
                    Property::ListUChar(v) => v.into_iter().map(u32::from).collect(),
                    Property::ListUShort(v) => v.into_iter().map(u32::from).collect(),
                    Property::ListUInt(v) => v,
                    Property::ListInt(v) => v
                        .into_iter()
                        .map(|i| u32::try_from(i).unwrap_or(NONE))
                        .collect(),
                    Property::ListShort(v) => v
                        .into_iter()
                        .map(|i| u32::try_from(i).unwrap_or(NONE))
                        .collect(),
                    _ => return PropertyAccessResult::Ignored,
                };
                return PropertyAccessResult::Set;
            }
            _ => return PropertyAccessResult::Ignored,
        };
        self.rgba[slot] = unit(&property);
        PropertyAccessResult::Set
    }
}

/// Linear RGBA of an element's colour, when it has red, green and blue.
fn color(e: &Elem) -> Option<[f32; 4]> {
    let [Some(r), Some(g), Some(b), a] = e.rgba else {
        return None;
    };
    let c = [r, g, b].map(|c| srgb_to_linear(c.clamp(0.0, 1.0)));
    Some([c[0], c[1], c[2], a.unwrap_or(1.0).clamp(0.0, 1.0)])
}

pub(crate) fn read(bytes: &[u8], path: &Path) -> Result<Appearance> {
    let ply = Parser::<Elem>::new()
        .read_ply(&mut &bytes[..])
        .map_err(|e| {
            parse_err(
                path,
                format!("PLY: {}", crate::io::plain_ply_error(&e.to_string())),
            )
        })?;
    let mut out = Appearance::default();
    if ply
        .header
        .comments
        .iter()
        .any(|c| c.trim_start().starts_with("TextureFile"))
    {
        out.facts
            .skip("PLY texture (`comment TextureFile`) and its coordinates");
    }
    let empty = Vec::new();
    let vertices = ply.payload.get("vertex").unwrap_or(&empty);
    let faces = ply.payload.get("face").unwrap_or(&empty);
    let s = &mut out.surface;
    s.positions = vertices.iter().map(|v| v.xyz).collect();
    let vertex_colors: Option<Vec<[f32; 4]>> = vertices.iter().map(color).collect();
    let n = s.positions.len();
    for f in faces {
        if f.indices.iter().any(|&i| i as usize >= n) {
            continue;
        }
        let fc = color(f);
        for k in 1..f.indices.len().saturating_sub(1) {
            let tri = [f.indices[0], f.indices[k], f.indices[k + 1]];
            let t = s.triangles.len();
            s.triangles.push(tri);
            if let Some(c) = fc {
                s.color.values.push(c);
                s.color.push(t, [s.color.values.len() as u32 - 1; 3]);
            }
        }
    }
    if let Some(vc) = vertex_colors.filter(|c| !c.is_empty() && s.color.corners.is_empty()) {
        s.color.values = vc;
        s.color.corners = s.triangles.clone();
    }
    Ok(out)
}
