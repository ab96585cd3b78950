//! Stanford PLY (ascii, binary little- and big-endian) via `ply-rs-bw`.
//!
//! Vertices are the `x`, `y`, `z` properties of the `vertex` element; faces the
//! `vertex_indices` (or `vertex_index`) list of the `face` element. Other elements and
//! properties are read past and ignored. Before the payload is parsed, the element counts in
//! the header are checked against what the rest of the file can hold. A face with a bad vertex
//! index (negative or not below the vertex count) is dropped and counted with its element
//! number (module docs of [`super`]).

use super::{bad_face, check_count, parse_err, push_polygon, LoadStats};
use crate::error::Result;
use crate::mesh::TriMesh;
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{
    Encoding, Property, PropertyAccess, PropertyAccessResult, PropertyType, ScalarType,
};
use std::path::Path;

/// One element of any kind: the parts of a vertex or a face we use.
#[derive(Debug, Default)]
struct Elem {
    xyz: [f32; 3],
    indices: Vec<u32>,
}

/// Converts a list of indices; a negative or too large one becomes `u32::MAX` (out of range).
fn to_u32<T: TryInto<u32> + Copy>(v: &[T]) -> Vec<u32> {
    v.iter()
        .map(|&x| x.try_into().unwrap_or(u32::MAX))
        .collect()
}

impl PropertyAccess for Elem {
    fn new() -> Self {
        Elem::default()
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        let axis = match name {
            "x" => Some(0),
            "y" => Some(1),
            "z" => Some(2),
            _ => None,
        };
        if let Some(a) = axis {
            if let Some(v) = property.to_f32_lossy() {
                self.xyz[a] = v;
                return PropertyAccessResult::Set;
            }
            return PropertyAccessResult::Ignored;
        }
        if name == "vertex_indices" || name == "vertex_index" {
            self.indices = match property {
                Property::ListChar(v) => to_u32(&v),
                Property::ListUChar(v) => to_u32(&v),
                Property::ListShort(v) => to_u32(&v),
                Property::ListUShort(v) => to_u32(&v),
                Property::ListInt(v) => to_u32(&v),
                Property::ListUInt(v) => v,
                _ => return PropertyAccessResult::Ignored,
            };
            return PropertyAccessResult::Set;
        }
        PropertyAccessResult::Ignored
    }
}

fn scalar_size(t: &ScalarType) -> usize {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// Where the payload starts: just after the `end_header` line.
fn payload_start(bytes: &[u8]) -> Option<usize> {
    let key = b"end_header";
    let at = bytes.windows(key.len()).position(|w| w == key)?;
    let nl = bytes[at..].iter().position(|&b| b == b'\n')?;
    Some(at + nl + 1)
}

pub(crate) fn read(bytes: &[u8], path: &Path, stats: &mut LoadStats) -> Result<TriMesh> {
    let parser = Parser::<Elem>::new();
    let header = parser.read_ply_header(&mut &bytes[..]).map_err(|e| {
        parse_err(
            path,
            format!("PLY header: {}", super::plain_ply_error(&e.to_string())),
        )
    })?;
    let start = payload_start(bytes).ok_or_else(|| parse_err(path, "PLY: no `end_header` line"))?;
    let payload = bytes.len() - start;

    // The smallest size each element can take; more elements than fit means a broken file.
    for (name, def) in &header.elements {
        let min = match header.encoding {
            Encoding::Ascii => 2,
            _ => def
                .properties
                .values()
                .map(|p| match &p.data_type {
                    PropertyType::Scalar(t) => scalar_size(t),
                    PropertyType::List(count, _) => scalar_size(count),
                })
                .sum::<usize>()
                .max(1),
        };
        if def.count.saturating_mul(min) > payload {
            return Err(parse_err(
                path,
                format!(
                    "PLY: the header declares {} `{name}` elements, more than the {payload} \
                     bytes after the header can hold (truncated?)",
                    def.count
                ),
            ));
        }
        check_count(path, name, def.count)?;
    }
    let has = |e: &str, p: &[&str]| {
        header
            .elements
            .get(e)
            .is_some_and(|d| p.iter().any(|n| d.properties.contains_key(*n)))
    };
    if !(has("vertex", &["x"]) && has("vertex", &["y"]) && has("vertex", &["z"])) {
        return Err(parse_err(path, "PLY: no `vertex` element with x, y, z"));
    }
    if !has("face", &["vertex_indices", "vertex_index"]) {
        return Err(crate::error::Error::EmptyMesh {
            context: path.display().to_string(),
            reason: "PLY without a `face` element with a `vertex_indices` list (a point cloud?)"
                .to_string(),
        });
    }

    let ply = parser.read_ply(&mut &bytes[..]).map_err(|e| {
        parse_err(
            path,
            format!("PLY: {}", super::plain_ply_error(&e.to_string())),
        )
    })?;
    let mut mesh = TriMesh::default();
    if let Some(vs) = ply.payload.get("vertex") {
        mesh.positions = vs.iter().map(|v| v.xyz).collect();
    }
    if let Some(fs) = ply.payload.get("face") {
        let n = mesh.positions.len();
        mesh.triangles.reserve(fs.len());
        for (k, f) in fs.iter().enumerate() {
            if let Some(&i) = f.indices.iter().find(|&&i| i as usize >= n) {
                bad_face(stats, || {
                    let index = if i == u32::MAX {
                        "negative or too large".to_string()
                    } else {
                        i.to_string()
                    };
                    format!(
                        "PLY face element {k}: vertex index {index} is out of range (the file \
                         has {n} vertices)"
                    )
                });
                continue;
            }
            push_polygon(&mut mesh.triangles, &f.indices, stats);
        }
    }
    Ok(mesh)
}
