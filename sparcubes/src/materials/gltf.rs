//! glTF 2.0 appearance: the metallic-roughness materials, their textures and samplers,
//! `KHR_texture_transform`, `TEXCOORD_0`/`_1` and `COLOR_0`, on the triangles of the same
//! scene walk as the shape's reader ([`crate::io`]), with the same node transforms.
//!
//! Read: `baseColorFactor` and `baseColorTexture`, `metallicFactor`, `roughnessFactor` and
//! `metallicRoughnessTexture` (metallic in blue, roughness in green, glTF 2.0 §3.9.2),
//! `alphaMode` and `alphaCutoff`, each texture's `texCoord` (0 or 1; a texture on another set
//! is named as not read), sampler wrap modes and
//! magnification filter, and `KHR_texture_transform` (parsed from the JSON itself, so the
//! shape's reader is unchanged). Images are PNG or JPEG, in a buffer view, a `data:` URI or a
//! file beside the glTF file. Named as not read: every material extension
//! (`KHR_materials_*`, specular-glossiness among them), emissive, normal and occlusion
//! textures, images in other formats or that fail to decode or have no source, and accessors
//! the `gltf` crate's readers cannot read (checked first: [`gltf_check`]).

use super::{gltf_check, gltf_images};
use super::{sibling, AlphaMode, Appearance, Material, ScalarMap, TextureBudget, TextureRef, Wrap};
use crate::error::Result;
use crate::io::gltf::{for_each_primitive, load_buffers, open, transform};
use crate::io::Buffers;
use gltf::texture::WrappingMode;
use serde_json::Value;
use std::path::Path;

pub(crate) fn read(
    bytes: &[u8],
    path: &Path,
    external: Buffers,
    budget: TextureBudget,
) -> Result<Appearance> {
    let doc = open(bytes, path)?;
    let buffers = load_buffers(&doc, path, external)?;
    let json = raw_json(bytes);
    let mut out = Appearance::default();
    out.materials = doc
        .materials()
        .map(|m| material(&m, &json, &mut out.facts))
        .collect();
    if let Some(scene) = doc.default_scene().or_else(|| doc.scenes().next()) {
        for_each_primitive(&scene, path, |prim, mesh, world| {
            primitive(prim, mesh, world, &buffers, &mut out);
            Ok(())
        })?;
    }
    gltf_images::decode_sampled(&doc, &buffers, path, external, budget, &mut out);
    Ok(out)
}

/// The JSON of a `.gltf` file, or of a `.glb` file's JSON chunk (for the extensions the
/// `gltf` crate is not built to read); `Null` when it cannot be found.
pub(super) fn raw_json(bytes: &[u8]) -> Value {
    let text = match glb_json_len(bytes) {
        Some(len) => bytes.get(20..20usize.saturating_add(len)).unwrap_or(&[]),
        None => bytes,
    };
    serde_json::from_slice(text).unwrap_or(Value::Null)
}

/// The length of a `.glb` file's JSON chunk, from its first 20 bytes (the file header and the
/// chunk's header); `None` when `head` does not start a `.glb` file.
pub(super) fn glb_json_len(head: &[u8]) -> Option<usize> {
    if head.len() < 20 || !head.starts_with(b"glTF") {
        return None;
    }
    Some(u32::from_le_bytes([head[12], head[13], head[14], head[15]]) as usize)
}

/// The material `m`, with what it uses that is not read named in `facts`.
fn material(m: &gltf::Material, json: &Value, facts: &mut super::Facts) -> Material {
    let index = m.index().unwrap_or(usize::MAX);
    let raw = &json["materials"][index];
    // Names come from the JSON: the `gltf` crate is built without its `names` feature.
    let name = raw["name"].as_str();
    let label = match name {
        Some(n) => format!("material {index} (`{}`)", sibling::clip(n)),
        None => format!("material {index}"),
    };
    if let Some(ext) = raw["extensions"].as_object() {
        for key in ext.keys() {
            facts.skip(format!("{label}: extension {key}"));
        }
    }
    for (key, what) in [
        ("emissiveTexture", "emissive texture"),
        ("normalTexture", "normal texture"),
        ("occlusionTexture", "occlusion texture"),
    ] {
        if !raw[key].is_null() {
            facts.skip(format!("{label}: {what}"));
        }
    }
    if raw["emissiveFactor"]
        .as_array()
        .is_some_and(|f| f.iter().any(|x| x.as_f64().is_some_and(|x| x != 0.0)))
    {
        facts.skip(format!("{label}: emissive colour"));
    }
    let pbr = m.pbr_metallic_roughness();
    let raw_pbr = &raw["pbrMetallicRoughness"];
    let mut read_set = |t: TextureRef, key: &str| {
        if t.set <= 1 {
            return Some(t);
        }
        facts.skip(format!(
            "{label}: {key} reads TEXCOORD_{} (only TEXCOORD_0 and TEXCOORD_1 are read)",
            t.set
        ));
        None
    };
    let base = pbr
        .base_color_texture()
        .map(|t| texture_ref(&t, &raw_pbr["baseColorTexture"]))
        .and_then(|t| read_set(t, "baseColorTexture"));
    let mr = pbr
        .metallic_roughness_texture()
        .map(|t| texture_ref(&t, &raw_pbr["metallicRoughnessTexture"]))
        .and_then(|t| read_set(t, "metallicRoughnessTexture"));
    Material {
        name: name.unwrap_or(&label).to_string(),
        base_color: pbr.base_color_factor(),
        base_color_map: base,
        metallic: pbr.metallic_factor(),
        metallic_map: mr.map(|texture| ScalarMap {
            texture,
            channel: 2,
        }),
        roughness: pbr.roughness_factor(),
        roughness_map: mr.map(|texture| ScalarMap {
            texture,
            channel: 1,
        }),
        alpha_map: None,
        alpha_mode: match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
            gltf::material::AlphaMode::Mask => AlphaMode::Mask(m.alpha_cutoff().unwrap_or(0.5)),
            gltf::material::AlphaMode::Blend => AlphaMode::Blend,
        },
    }
}

/// A texture reference from a `textureInfo`, with its sampler and `KHR_texture_transform`
/// (read from `raw`, the textureInfo's JSON).
fn texture_ref(info: &gltf::texture::Info, raw: &Value) -> TextureRef {
    let tex = info.texture();
    let sampler = tex.sampler();
    let wrap = |w: WrappingMode| match w {
        WrappingMode::ClampToEdge => Wrap::Clamp,
        WrappingMode::MirroredRepeat => Wrap::Mirror,
        WrappingMode::Repeat => Wrap::Repeat,
    };
    let mut out = TextureRef {
        image: tex.source().index(),
        set: info.tex_coord() as usize,
        transform: super::IDENTITY_UV,
        wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
        nearest: sampler.mag_filter() == Some(gltf::texture::MagFilter::Nearest),
    };
    let t = &raw["extensions"]["KHR_texture_transform"];
    if t.is_object() {
        let num = |v: &Value, d: f64| v.as_f64().unwrap_or(d);
        let (ox, oy) = (num(&t["offset"][0], 0.0), num(&t["offset"][1], 0.0));
        let (sx, sy) = (num(&t["scale"][0], 1.0), num(&t["scale"][1], 1.0));
        let r = num(&t["rotation"], 0.0);
        let (s, c) = r.sin_cos();
        // translation · rotation · scale, rotation [[c, s], [−s, c]] (row-major): the
        // ratified KHR_texture_transform README, as three.js and Babylon.js apply it.
        out.transform = [
            [(c * sx) as f32, (s * sy) as f32, ox as f32],
            [(-s * sx) as f32, (c * sy) as f32, oy as f32],
        ];
        if let Some(set) = t["texCoord"].as_u64() {
            out.set = set as usize;
        }
    }
    out
}

/// The accessor of `semantic` in `prim`, when it has one the `gltf` crate can read as one of
/// `allowed` ([`gltf_check`]); one it cannot is named in `facts` as `label: NAME not read`.
fn checked<'a>(
    prim: &gltf::Primitive<'a>,
    semantic: gltf::Semantic,
    allowed: &[gltf_check::Kind],
    buffers: &[Vec<u8>],
    label: &str,
    facts: &mut super::Facts,
) -> Option<gltf::Accessor<'a>> {
    let acc = prim.get(&semantic)?;
    match gltf_check::unreadable(&acc, allowed, buffers) {
        None => Some(acc),
        Some(why) => {
            facts.skip(format!(
                "{label}: {} not read ({why})",
                semantic_name(&semantic)
            ));
            None
        }
    }
}

/// A semantic's name in the file, `TEXCOORD_0`.
fn semantic_name(semantic: &gltf::Semantic) -> String {
    match semantic {
        gltf::Semantic::Positions => "POSITION".into(),
        gltf::Semantic::TexCoords(s) => format!("TEXCOORD_{s}"),
        gltf::Semantic::Colors(s) => format!("COLOR_{s}"),
        _ => "an attribute".into(),
    }
}

/// The values of a per-vertex attribute read by `read`, kept when there is one per vertex
/// (`n`); one of another count is named in `facts`.
fn per_vertex<T>(
    values: Option<Vec<T>>,
    n: usize,
    what: &str,
    label: &str,
    facts: &mut super::Facts,
) -> Option<Vec<T>> {
    let v = values?;
    if v.len() == n {
        return Some(v);
    }
    facts.skip(format!(
        "{label}: {what} not read ({} values for {n} vertices)",
        v.len()
    ));
    None
}

/// The primitive's indices, or every vertex in order when it has none; `None` (named in
/// `facts`) when they cannot be read.
fn indices(
    prim: &gltf::Primitive,
    buffers: &[Vec<u8>],
    n: usize,
    label: &str,
    facts: &mut super::Facts,
) -> Option<Vec<u32>> {
    let Some(acc) = prim.indices() else {
        return Some((0..n as u32).collect());
    };
    if let Some(why) = gltf_check::unreadable(&acc, gltf_check::INDICES, buffers) {
        facts.skip(format!(
            "{label}: its indices cannot be read ({why}): its appearance is not read"
        ));
        return None;
    }
    let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let read = reader.read_indices().map(|i| i.into_u32().collect());
    if read.is_none() {
        facts.skip(format!(
            "{label}: its indices cannot be read: its appearance is not read"
        ));
    }
    read
}

/// Appends one primitive's triangles with their corners' texture coordinates and colours;
/// what of it cannot be read is named in the facts and left out.
fn primitive(
    prim: &gltf::Primitive,
    mesh: usize,
    world: &[[f64; 4]; 4],
    buffers: &[Vec<u8>],
    out: &mut Appearance,
) {
    use gltf::mesh::Mode;
    use gltf::Semantic;
    if !matches!(
        prim.mode(),
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
    ) {
        return;
    }
    let label = format!("mesh {mesh} primitive {}", prim.index());
    let facts = &mut out.facts;
    let positions = checked(
        prim,
        Semantic::Positions,
        gltf_check::POSITIONS,
        buffers,
        &label,
        facts,
    );
    let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let Some(positions) = positions.and_then(|_| reader.read_positions()) else {
        return;
    };
    let positions: Vec<[f32; 3]> = positions
        .map(|p| {
            let q = transform(world, [p[0] as f64, p[1] as f64, p[2] as f64]);
            [q[0] as f32, q[1] as f32, q[2] as f32]
        })
        .collect();
    let n = positions.len();
    let Some(indices) = indices(prim, buffers, n, &label, facts) else {
        return;
    };
    let uv: [Option<Vec<[f32; 2]>>; 2] = [0, 1].map(|s| {
        let acc = checked(
            prim,
            Semantic::TexCoords(s),
            gltf_check::TEX_COORDS,
            buffers,
            &label,
            facts,
        );
        let read = acc
            .and_then(|_| reader.read_tex_coords(s))
            .map(|t| t.into_f32().collect());
        per_vertex(read, n, &format!("TEXCOORD_{s}"), &label, facts)
    });
    let color = checked(
        prim,
        Semantic::Colors(0),
        gltf_check::COLOURS,
        buffers,
        &label,
        facts,
    );
    let color = color
        .and_then(|_| reader.read_colors(0))
        .map(|c| c.into_rgba_f32().collect());
    let color = per_vertex(color, n, "COLOR_0", &label, facts);
    let material = prim.material().index().map(|i| i as u32);
    append(
        out,
        &positions,
        &indices,
        prim.mode(),
        &uv,
        color.as_deref(),
        material,
    );
}

/// Appends triangles of `mode` over `indices` into `positions` to the surface, with their
/// corners' coordinate sets and colours where the primitive has them, and `material` (the
/// default one after the file's when `None`).
fn append(
    out: &mut Appearance,
    positions: &[[f32; 3]],
    indices: &[u32],
    mode: gltf::mesh::Mode,
    uv: &[Option<Vec<[f32; 2]>>; 2],
    color: Option<&[[f32; 4]]>,
    material: Option<u32>,
) {
    let n = positions.len();
    let surface = &mut out.surface;
    let base = surface.positions.len() as u32;
    surface.positions.extend(positions);
    let uv_base = [0, 1].map(|s| surface.uv[s].values.len() as u32);
    for (s, v) in uv.iter().enumerate() {
        if let Some(v) = v {
            surface.uv[s].values.extend(v);
        }
    }
    let color_base = surface.color.values.len() as u32;
    if let Some(c) = color {
        surface.color.values.extend(c);
    }
    let material = material.unwrap_or(out.materials.len() as u32);
    for tri in triangles(mode, indices) {
        if tri.iter().any(|&i| i as usize >= n) {
            continue;
        }
        let t = surface.triangles.len();
        surface.triangles.push(tri.map(|i| base + i));
        surface.material.push(material);
        for s in 0..2 {
            if uv[s].is_some() {
                surface.uv[s].push(t, tri.map(|i| uv_base[s] + i));
            }
        }
        if color.is_some() {
            surface.color.push(t, tri.map(|i| color_base + i));
        }
    }
}

/// The triangles of a list, strip or fan of indices (strips with every other one flipped).
fn triangles(mode: gltf::mesh::Mode, idx: &[u32]) -> Vec<[u32; 3]> {
    use gltf::mesh::Mode;
    let n = idx.len();
    match mode {
        Mode::Triangles => idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        Mode::TriangleStrip => (0..n.saturating_sub(2))
            .map(|k| match k % 2 {
                0 => [idx[k], idx[k + 1], idx[k + 2]],
                _ => [idx[k + 1], idx[k], idx[k + 2]],
            })
            .collect(),
        _ => (1..n.saturating_sub(1))
            .map(|k| [idx[0], idx[k], idx[k + 1]])
            .collect(),
    }
}
