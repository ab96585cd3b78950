//! glTF images, decoded only where a texel is sampled and once per source (issue 64 item 4:
//! every image entry was decoded, unused ones and repeats of one file included, so 1.4 KB of
//! glTF naming one 260 KB PNG twelve times peaked at 3.5 GB).
//!
//! An image is decoded when a texture of a material that some triangle uses, on a coordinate
//! set those triangles carry, reads it; entries naming the same source (the same file beside
//! the glTF file, the same `data:` URI, the same buffer view) are one image, decoded once, and
//! every texture reading any of them reads that one. Images no sampled texture reads are
//! left undecoded (`None`) and are not named: nothing of them was to be read.

use super::image::Image;
use super::{sibling, Appearance, Material, TextureBudget};
use crate::io::Buffers;
use base64::Engine as _;
use std::collections::HashMap;
use std::path::Path;

/// Decodes the images the surface samples into `out.images` (one entry per image of the
/// document, `None` where not decoded), each source once, and points every material's
/// textures at the entry decoded for their source. `path` and `external` locate files beside
/// the glTF file; images past the `budget` are named and not decoded.
pub(super) fn decode_sampled(
    doc: &gltf::Gltf,
    buffers: &[Vec<u8>],
    path: &Path,
    external: Buffers,
    mut budget: TextureBudget,
    out: &mut Appearance,
) {
    let count = doc.images().len();
    let sampled = sampled_images(out, count);
    let mut decoded_for: HashMap<String, usize> = HashMap::new();
    let mut canonical: Vec<usize> = (0..count).collect();
    out.images = vec![None; count];
    for i in (0..count).filter(|&i| sampled[i]) {
        let key = source_key(doc, i);
        if let Some(&first) = key.as_ref().and_then(|k| decoded_for.get(k)) {
            canonical[i] = first;
            continue;
        }
        if let Some(k) = key {
            decoded_for.insert(k, i);
        }
        let bytes = image_bytes(doc, i, buffers, path, external);
        out.images[i] = decode_image(i, bytes, &mut budget, &mut out.facts);
    }
    for m in &mut out.materials {
        point_at(m, &canonical);
    }
}

/// For each of the document's `count` images, whether a texture that is sampled reads it.
fn sampled_images(out: &Appearance, count: usize) -> Vec<bool> {
    let mut sampled = vec![false; count];
    for (m, sets) in out.materials.iter().zip(out.coordinate_sets()) {
        let Some(sets) = sets else { continue };
        for t in m.textures().filter(|t| sets[t.set.min(1)]) {
            if let Some(s) = sampled.get_mut(t.image) {
                *s = true;
            }
        }
    }
    sampled
}

/// Points the material's textures at the image decoded for their source.
fn point_at(m: &mut Material, canonical: &[usize]) {
    let at = |i: usize| canonical.get(i).copied().unwrap_or(i);
    if let Some(t) = &mut m.base_color_map {
        t.image = at(t.image);
    }
    for map in [&mut m.metallic_map, &mut m.roughness_map, &mut m.alpha_map]
        .into_iter()
        .flatten()
    {
        map.texture.image = at(map.texture.image);
    }
}

/// What image `index` is read from, the same text for entries of one source: its buffer
/// view, its `data:` URI, or its file's path in plain components; `None` without a source.
fn source_key(doc: &gltf::Gltf, index: usize) -> Option<String> {
    let raw = doc.as_json().images.get(index)?;
    if let Some(view) = raw.buffer_view {
        return Some(format!("view {}", view.value()));
    }
    let uri = raw.uri.as_deref()?;
    if uri.starts_with("data:") {
        return Some(format!("uri {uri}"));
    }
    let name = crate::io::gltf::percent_decode(uri)?.replace('\\', "/");
    let plain: Vec<&str> = name
        .split('/')
        .filter(|p| !p.is_empty() && *p != ".")
        .collect();
    Some(format!("file {}", plain.join("/")))
}

/// The bytes of an image: a buffer view, a `data:` URI or a file beside the glTF file. Read
/// from the document's JSON, not through `gltf::Image::source`, which panics on an image with
/// neither a `uri` nor a `bufferView`, or with a `bufferView` but no `mimeType` (issue 61);
/// the format is told by its signature either way ([`super::image::decode`]).
fn image_bytes(
    doc: &gltf::Gltf,
    index: usize,
    buffers: &[Vec<u8>],
    path: &Path,
    external: Buffers,
) -> std::result::Result<Vec<u8>, String> {
    let raw = doc.as_json().images.get(index).ok_or("it is missing")?;
    if let Some(view) = raw.buffer_view {
        let view = doc
            .views()
            .nth(view.value())
            .ok_or("its buffer view is missing")?;
        let data = buffers
            .get(view.buffer().index())
            .ok_or("its buffer is missing")?;
        let end = view.offset().checked_add(view.length());
        return end
            .and_then(|e| data.get(view.offset()..e))
            .map(<[u8]>::to_vec)
            .ok_or_else(|| "its buffer view runs past its buffer".to_string());
    }
    let uri = raw
        .uri
        .as_deref()
        .ok_or("it has neither a `uri` nor a `bufferView`")?;
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest
            .split_once(";base64,")
            .ok_or("only base64 data URIs are read")?;
        return base64::engine::general_purpose::STANDARD
            .decode(payload.trim())
            .map_err(|e| format!("bad base64: {e}"));
    }
    let name = crate::io::gltf::percent_decode(uri).ok_or("bad percent-encoding")?;
    sibling::read_image(&name, path, external)
        .map_err(|e| format!("`{}`: {e}", sibling::clip(&name)))
}

/// Decodes image `index` from its `bytes` within the `budget`; one that cannot be read is
/// `None` and named in `facts`.
fn decode_image(
    index: usize,
    bytes: Result<Vec<u8>, String>,
    budget: &mut TextureBudget,
    facts: &mut super::Facts,
) -> Option<Image> {
    let decoded = bytes.and_then(|b| budget.decode(&b));
    match decoded {
        Ok(image) => Some(image),
        Err(why) => {
            facts.skip(format!("image {index}: {why}"));
            None
        }
    }
}
