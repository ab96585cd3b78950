//! glTF 2.0 (`.gltf` JSON and `.glb` binary) via `gltf`.
//!
//! Every triangle primitive (`TRIANGLES`, `TRIANGLE_STRIP`, `TRIANGLE_FAN`) of every mesh
//! instance in the default scene (or the first scene when none is the default) is read, with
//! the node transforms composed down the hierarchy. Points and lines are counted, not read.
//! A node reached through several parents is an instance each time: before anything is read,
//! the hierarchy is walked once to count node instances (at most [`MAX_NODE_INSTANCES`]) and
//! the vertices and triangles they would produce (at most [`MAX_ELEMENTS`] each), so a small
//! file whose nodes share children cannot expand exponentially. A triangle with a bad vertex
//! index is dropped and counted (module docs of [`super`]).
//!
//! Only buffers are imported, never images. An external buffer is either a `data:` URI
//! (base64) or a relative path inside the glTF file's own folder: absolute paths, `..`
//! components and every other URI scheme are refused, and so is a path that resolves (through
//! symbolic links) to a file outside that folder, so a file can never make us read elsewhere
//! on disk or touch the network. A file fetched from a URL hands in a reader for such checked
//! relative paths ([`Buffers::Relative`]), which fetches them under the file's own prefix.
//! Accessors are read by hand with checked bounds.

use super::{bad_face, check_count, parse_err, too_large, Buffers, LoadStats, MAX_ELEMENTS};
use crate::error::{Error, Result};
use crate::mesh::TriMesh;
use base64::Engine as _;
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;
use std::path::{Component, Path};

/// Deepest node hierarchy followed (deeper means a cycle or an absurd file).
const MAX_DEPTH: usize = 256;

/// Most node instances read from one file (a node reached through k paths from the scene
/// counts k times). Large CAD assemblies place some ten thousand parts; a million instances
/// is far beyond any real scene and small enough to count in milliseconds.
pub const MAX_NODE_INSTANCES: usize = 1 << 20;

/// Walks the scene's node instances without reading any data, and refuses the file before
/// anything is allocated when the instances, or the vertices or triangles they would
/// produce, exceed the limits.
pub(crate) fn check_expansion(scene: &gltf::Scene, path: &Path) -> Result<()> {
    let mut stack: Vec<(gltf::Node, usize)> = scene.nodes().map(|n| (n, 0)).collect();
    let (mut instances, mut vertices, mut triangles) = (0usize, 0usize, 0usize);
    while let Some((node, depth)) = stack.pop() {
        instances += 1;
        if depth > MAX_DEPTH {
            return Err(parse_err(path, "glTF: node hierarchy too deep or cyclic"));
        }
        if instances > MAX_NODE_INSTANCES {
            return Err(too_large(
                path,
                format!(
                    "glTF: the node hierarchy expands to more than {MAX_NODE_INSTANCES} node \
                     instances (nodes shared by several parents count once per path)"
                ),
            ));
        }
        if let Some(m) = node.mesh() {
            for prim in m.primitives() {
                let n = prim
                    .indices()
                    .or_else(|| prim.get(&gltf::Semantic::Positions))
                    .map_or(0, |a| a.count());
                let n = match prim.mode() {
                    Mode::Triangles => n / 3,
                    Mode::TriangleStrip | Mode::TriangleFan => n.saturating_sub(2),
                    _ => 0,
                };
                vertices = vertices.saturating_add(
                    prim.get(&gltf::Semantic::Positions)
                        .map_or(0, |a| a.count()),
                );
                triangles = triangles.saturating_add(n);
            }
            if vertices > MAX_ELEMENTS || triangles > MAX_ELEMENTS {
                return Err(too_large(
                    path,
                    format!(
                        "glTF: its {instances}+ node instances place more than {MAX_ELEMENTS} \
                         vertices or triangles"
                    ),
                ));
            }
        }
        stack.extend(node.children().map(|c| (c, depth + 1)));
    }
    Ok(())
}

pub(crate) fn read(
    bytes: &[u8],
    path: &Path,
    external: Buffers,
    stats: &mut LoadStats,
) -> Result<TriMesh> {
    let gltf = open(bytes, path)?;
    let buffers = load_buffers(&gltf, path, external)?;

    let scene = gltf
        .default_scene()
        .or_else(|| gltf.scenes().next())
        .ok_or_else(|| Error::EmptyMesh {
            context: path.display().to_string(),
            reason: "glTF without a scene".to_string(),
        })?;

    let mut mesh = TriMesh::default();
    for_each_primitive(&scene, path, |prim, mesh_index, world| {
        read_primitive(prim, mesh_index, world, &buffers, path, stats, &mut mesh)
    })?;
    Ok(mesh)
}

/// Calls `each` with every primitive of `scene`'s nodes, the index of its mesh and its node's
/// world transform, depth first from the last root (the one order in which the shape and its
/// appearance, `crate::materials`, are both read), once instancing is checked not to expand
/// past the limit.
pub(crate) fn for_each_primitive(
    scene: &gltf::Scene,
    path: &Path,
    mut each: impl FnMut(&gltf::Primitive, usize, &[[f64; 4]; 4]) -> Result<()>,
) -> Result<()> {
    check_expansion(scene, path)?;
    let mut stack: Vec<(gltf::Node, [[f64; 4]; 4])> =
        scene.nodes().map(|n| (n, IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        let world = mul(&parent, &to_f64(node.transform().matrix()));
        if let Some(m) = node.mesh() {
            for prim in m.primitives() {
                each(&prim, m.index(), &world)?;
            }
        }
        stack.extend(node.children().map(|c| (c, world)));
    }
    Ok(())
}

/// Parses and validates the document. Missing POSITION `min`/`max` (common in exported files,
/// and never used here) is tolerated; glTF 1.0 and required extensions we cannot read (Draco
/// compression, ...) are reported as unsupported formats.
pub(crate) fn open(bytes: &[u8], path: &Path) -> Result<gltf::Gltf> {
    let unsupported = |reason: String| Error::UnsupportedFormat {
        path: path.to_path_buf(),
        reason,
    };
    if bytes.starts_with(b"glTF") && bytes.get(4..8) == Some(&1u32.to_le_bytes()[..]) {
        return Err(unsupported(
            "binary glTF 1.0 (only glTF 2.0 is read)".into(),
        ));
    }
    match gltf::Gltf::from_slice(bytes) {
        Ok(g) => Ok(g),
        Err(gltf::Error::Validation(errors)) => {
            let only_bounds = errors.iter().all(|(p, e)| {
                matches!(e, gltf::json::validation::Error::Missing)
                    && (p.0.ends_with(".min") || p.0.ends_with(".max"))
            });
            if only_bounds {
                return gltf::Gltf::from_slice_without_validation(bytes)
                    .map_err(|e| parse_err(path, format!("glTF: {e}")));
            }
            let list: Vec<String> = errors
                .iter()
                .take(5)
                .map(|(p, e)| format!("{p}: {e}"))
                .collect();
            let text = format!("invalid glTF: {}", list.join("; "));
            if errors
                .iter()
                .any(|(p, _)| p.0.starts_with("extensionsRequired"))
            {
                Err(unsupported(text))
            } else {
                Err(parse_err(path, format!("glTF: {text}")))
            }
        }
        Err(e) => {
            let v1 = serde_json::from_slice::<serde_json::Value>(bytes)
                .ok()
                .and_then(|v| v["asset"]["version"].as_str().map(|s| s.starts_with('1')))
                .unwrap_or(false);
            if v1 {
                Err(unsupported("glTF 1.0 (only glTF 2.0 is read)".into()))
            } else {
                Err(parse_err(path, format!("glTF: {e}")))
            }
        }
    }
}

/// The data of every buffer, in order.
pub(crate) fn load_buffers(
    gltf: &gltf::Gltf,
    path: &Path,
    external: Buffers,
) -> Result<Vec<Vec<u8>>> {
    let mut out = Vec::new();
    for buffer in gltf.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
                .clone()
                .ok_or_else(|| parse_err(path, "glTF: buffer refers to a missing GLB BIN chunk"))?,
            gltf::buffer::Source::Uri(uri) => read_uri(uri, path, external)?,
        };
        if data.len() < buffer.length() {
            return Err(parse_err(
                path,
                format!(
                    "glTF: buffer {} has {} bytes, less than its declared {} (truncated?)",
                    buffer.index(),
                    data.len(),
                    buffer.length()
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// Reads a buffer URI: `data:` base64, or a relative path inside the file's folder (on disk,
/// or through `external`'s reader).
fn read_uri(uri: &str, path: &Path, external: Buffers) -> Result<Vec<u8>> {
    let refuse = |why: &str| {
        parse_err(
            path,
            format!("glTF: refusing buffer uri `{}`: {why}", clip(uri)),
        )
    };
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest
            .split_once(";base64,")
            .ok_or_else(|| refuse("only base64 data URIs are supported"))?;
        return base64::engine::general_purpose::STANDARD
            .decode(payload.trim())
            .map_err(|e| refuse(&format!("bad base64: {e}")));
    }
    // A scheme ("http:", "file:", ...) is letters, digits, + - . before the first ':'.
    if let Some((scheme, _)) = uri.split_once(':') {
        if !scheme.is_empty()
            && scheme
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
        {
            return Err(refuse("only relative paths and data: URIs are read"));
        }
    }
    let decoded = percent_decode(uri).ok_or_else(|| refuse("bad percent-encoding"))?;
    if decoded.contains('\\') || decoded.contains('\0') {
        return Err(refuse("backslashes and NUL are not allowed"));
    }
    let rel = Path::new(&decoded);
    if rel
        .components()
        .any(|c| !matches!(c, Component::Normal(_) | Component::CurDir))
    {
        return Err(refuse("absolute paths and `..` components are not allowed"));
    }
    if let Buffers::Relative(reader) = external {
        let plain: Vec<&str> = decoded
            .split('/')
            .filter(|p| !p.is_empty() && *p != ".")
            .collect();
        return reader(&plain.join("/")).map_err(|e| {
            parse_err(
                path,
                format!("glTF: cannot read buffer `{}`: {e}", clip(uri)),
            )
        });
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let file = dir.join(rel);
    let cannot = |e: &dyn std::fmt::Display| {
        parse_err(
            path,
            format!("glTF: cannot read buffer `{}`: {e}", file.display()),
        )
    };
    // Links are resolved: the file really read must lie inside the glTF file's own folder.
    let real_dir = std::fs::canonicalize(dir).map_err(|e| cannot(&e))?;
    let real = std::fs::canonicalize(&file).map_err(|e| cannot(&e))?;
    if !real.starts_with(&real_dir) {
        return Err(refuse(&format!(
            "it resolves to `{}`, outside the glTF file's folder",
            real.display()
        )));
    }
    super::read_file(&real).map_err(|e| match e {
        Error::TooLarge { .. } => e,
        other => cannot(&other),
    })
}

/// Decodes `%XX` escapes; `None` when one is malformed or the result is not UTF-8.
pub(crate) fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = std::str::from_utf8(b.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

fn clip(s: &str) -> String {
    s.chars().take(60).collect()
}

/// Counts the points or line segments of a primitive that is not made of triangles (they are
/// skipped) and says whether it was one.
fn count_non_triangles(mode: Mode, n: usize, stats: &mut LoadStats) -> bool {
    match mode {
        Mode::Points => stats.points_skipped += n as u64,
        Mode::Lines => stats.lines_skipped += (n / 2) as u64,
        Mode::LineStrip => stats.lines_skipped += n.saturating_sub(1) as u64,
        Mode::LineLoop => stats.lines_skipped += n as u64,
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan => return false,
    }
    true
}

/// Appends the triangles of a triangle list, strip or fan of `n` indices (`idx(k)`: the mesh
/// vertex of the k-th index), strips with every other triangle flipped to keep the winding.
fn push_triangles(mode: Mode, n: usize, idx: impl Fn(usize) -> u32, out: &mut Vec<[u32; 3]>) {
    match mode {
        Mode::Triangles => {
            for k in 0..n / 3 {
                out.push([idx(3 * k), idx(3 * k + 1), idx(3 * k + 2)]);
            }
        }
        Mode::TriangleStrip => {
            for k in 0..n.saturating_sub(2) {
                if k % 2 == 0 {
                    out.push([idx(k), idx(k + 1), idx(k + 2)]);
                } else {
                    out.push([idx(k + 1), idx(k), idx(k + 2)]);
                }
            }
        }
        _ => {
            for k in 1..n.saturating_sub(1) {
                out.push([idx(0), idx(k), idx(k + 1)]);
            }
        }
    }
}

fn read_primitive(
    prim: &gltf::Primitive,
    mesh_index: usize,
    world: &[[f64; 4]; 4],
    buffers: &[Vec<u8>],
    path: &Path,
    stats: &mut LoadStats,
    mesh: &mut TriMesh,
) -> Result<()> {
    let Some(pos_acc) = prim.get(&gltf::Semantic::Positions) else {
        return Ok(());
    };
    let mode = prim.mode();
    let n_vertices = pos_acc.count();
    let indices: Option<Vec<u32>> = match prim.indices() {
        Some(acc) => Some(
            read_accessor(&acc, buffers, path)?
                .into_iter()
                .map(|v| {
                    if v[0] >= 0.0 && v[0] <= u32::MAX as f64 {
                        v[0] as u32
                    } else {
                        u32::MAX
                    }
                })
                .collect(),
        ),
        None => None,
    };
    let n = indices.as_ref().map_or(n_vertices, Vec::len);
    if count_non_triangles(mode, n, stats) {
        return Ok(());
    }

    let positions = read_accessor(&pos_acc, buffers, path)?;
    let base = mesh.positions.len();
    check_count(path, "vertices", base + positions.len())?;
    let base = base as u32;
    let identity = *world == IDENTITY;
    mesh.positions.extend(positions.iter().map(|p| {
        // Untransformed points are copied exactly (even the sign of a zero).
        let q = if identity { *p } else { transform(world, *p) };
        [q[0] as f32, q[1] as f32, q[2] as f32]
    }));
    let idx = |k: usize| -> u32 {
        let i = indices.as_ref().map_or(k as u32, |v| v[k]);
        if (i as usize) < positions.len() {
            base + i
        } else {
            u32::MAX
        }
    };
    let before = mesh.triangles.len();
    push_triangles(mode, n, idx, &mut mesh.triangles);
    // Triangles with a bad vertex index are dropped and counted.
    if mesh.triangles[before..]
        .iter()
        .any(|t| t.contains(&u32::MAX))
    {
        let added = mesh.triangles.split_off(before);
        for (k, t) in added.into_iter().enumerate() {
            if !t.contains(&u32::MAX) {
                mesh.triangles.push(t);
                continue;
            }
            bad_face(stats, || {
                format!(
                    "glTF mesh {mesh_index} primitive {} triangle {k}: a vertex index is out \
                     of range (the primitive has {} vertices)",
                    prim.index(),
                    positions.len()
                )
            });
        }
    }
    // A mirroring transform flips the winding; flip it back.
    if det3(world) < 0.0 {
        for t in &mut mesh.triangles[before..] {
            t.swap(1, 2);
        }
    }
    check_count(path, "triangles", mesh.triangles.len())
}

/// Reads an accessor's elements (up to 3 components each) as f64, with bounds checked.
fn read_accessor(acc: &gltf::Accessor, buffers: &[Vec<u8>], path: &Path) -> Result<Vec<[f64; 3]>> {
    let err = |why: String| parse_err(path, format!("glTF accessor {}: {why}", acc.index()));
    if acc.sparse().is_some() {
        return Err(err("sparse accessors are not supported".into()));
    }
    let comps = match acc.dimensions() {
        Dimensions::Scalar => 1,
        Dimensions::Vec2 => 2,
        Dimensions::Vec3 => 3,
        other => return Err(err(format!("unexpected type {other:?}"))),
    };
    let dt = acc.data_type();
    let size = match dt {
        DataType::I8 | DataType::U8 => 1,
        DataType::I16 | DataType::U16 => 2,
        DataType::U32 | DataType::F32 => 4,
    };
    let count = acc.count();
    check_count(path, "accessor elements", count)?;
    let Some(view) = acc.view() else {
        return Err(err("no buffer view".into()));
    };
    let data = buffers
        .get(view.buffer().index())
        .ok_or_else(|| err("missing buffer".into()))?;
    let elem = comps * size;
    let stride = view.stride().unwrap_or(elem).max(elem);
    let view_start = view.offset();
    let view_end = view_start
        .checked_add(view.length())
        .filter(|&e| e <= data.len())
        .ok_or_else(|| err("buffer view runs past its buffer".into()))?;
    let bytes = &data[view_start..view_end];
    let need = match count {
        0 => 0,
        c => (c - 1)
            .checked_mul(stride)
            .and_then(|x| x.checked_add(elem))
            .and_then(|x| x.checked_add(acc.offset()))
            .unwrap_or(usize::MAX),
    };
    if need > bytes.len() {
        return Err(err(format!(
            "needs {need} bytes, its buffer view has {}",
            bytes.len()
        )));
    }
    let norm = acc.normalized();
    let mut out = Vec::with_capacity(count);
    for k in 0..count {
        let at = acc.offset() + k * stride;
        let mut v = [0.0f64; 3];
        for (c, slot) in v.iter_mut().enumerate().take(comps) {
            let o = at + c * size;
            let b = &bytes[o..o + size];
            *slot = match dt {
                DataType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                DataType::U16 => {
                    let x = u16::from_le_bytes([b[0], b[1]]) as f64;
                    if norm {
                        x / 65535.0
                    } else {
                        x
                    }
                }
                DataType::I16 => {
                    let x = i16::from_le_bytes([b[0], b[1]]) as f64;
                    if norm {
                        (x / 32767.0).max(-1.0)
                    } else {
                        x
                    }
                }
                DataType::U8 => {
                    let x = b[0] as f64;
                    if norm {
                        x / 255.0
                    } else {
                        x
                    }
                }
                DataType::I8 => {
                    let x = b[0] as i8 as f64;
                    if norm {
                        (x / 127.0).max(-1.0)
                    } else {
                        x
                    }
                }
            };
        }
        out.push(v);
    }
    Ok(out)
}

pub(crate) const IDENTITY: [[f64; 4]; 4] = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

pub(crate) fn to_f64(m: [[f32; 4]; 4]) -> [[f64; 4]; 4] {
    m.map(|c| c.map(f64::from))
}

/// Product of column-major matrices `a * b`.
pub(crate) fn mul(a: &[[f64; 4]; 4], b: &[[f64; 4]; 4]) -> [[f64; 4]; 4] {
    let mut r = [[0.0; 4]; 4];
    for (c, col) in r.iter_mut().enumerate() {
        for (row, x) in col.iter_mut().enumerate() {
            *x = (0..4).map(|k| a[k][row] * b[c][k]).sum();
        }
    }
    r
}

/// Applies a column-major affine matrix to a point.
pub(crate) fn transform(m: &[[f64; 4]; 4], p: [f64; 3]) -> [f64; 3] {
    let mut q = [0.0; 3];
    for (row, x) in q.iter_mut().enumerate() {
        *x = m[0][row] * p[0] + m[1][row] * p[1] + m[2][row] * p[2] + m[3][row];
    }
    q
}

/// Determinant of the linear part of a column-major matrix.
fn det3(m: &[[f64; 4]; 4]) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}
