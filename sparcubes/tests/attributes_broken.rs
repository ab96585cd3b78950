//! glTF appearance the `gltf` crate cannot read safely (issue 61: a `COLOR_0` accessor of a
//! type colours cannot have, an image with neither `uri` nor `bufferView`; issue 64 item 6: a
//! texture whose coordinates cannot be read): the shape converts, the appearance is read
//! without a panic, and what was not read is named.

use base64::Engine as _;
use serde_json::{json, Value};
use sparcubes::attributes::sample;
use sparcubes::io::Buffers;
use sparcubes::materials::{self, Appearance};
use sparcubes::Params;
use std::path::{Path, PathBuf};

type TestResult = Result<(), Box<dyn std::error::Error>>;

/// A 2 × 2 PNG, all red.
fn red_png() -> Vec<u8> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, 2, 2);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    match enc.write_header() {
        Ok(mut w) => w
            .write_image_data(&[255, 0, 0, 255].repeat(4))
            .unwrap_or_else(|e| panic!("{e}")),
        Err(e) => panic!("{e}"),
    }
    out
}

fn data_uri(mime: &str, bytes: &[u8]) -> String {
    format!(
        "data:{mime};base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// The buffer, views and accessors of a glTF document being built.
#[derive(Default)]
struct Doc {
    buf: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Doc {
    /// Adds `bytes` as a buffer view and an accessor of `count` elements of `kind` and
    /// component type `ctype` over it; its index.
    fn add(&mut self, bytes: &[u8], count: usize, kind: &str, ctype: u32) -> usize {
        self.views
            .push(json!({"buffer": 0, "byteOffset": self.buf.len(), "byteLength": bytes.len()}));
        self.accessors
            .push(json!({"bufferView": self.views.len() - 1,
            "componentType": ctype, "count": count, "type": kind}));
        self.buf.extend(bytes);
        self.accessors.len() - 1
    }

    /// Adds raw bytes as a buffer view only; its index.
    fn view(&mut self, bytes: &[u8]) -> usize {
        self.views
            .push(json!({"buffer": 0, "byteOffset": self.buf.len(), "byteLength": bytes.len()}));
        self.buf.extend(bytes);
        self.views.len() - 1
    }
}

fn floats(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// The unit quad (two triangles) with `TEXCOORD_0`, a base colour texture on it (image 0),
/// and whatever `edit` adds to the document, its primitive and its JSON.
fn quad(edit: impl FnOnce(&mut Doc, &mut serde_json::Map<String, Value>, &mut Value)) -> String {
    let mut doc = Doc::default();
    let corners = [[0.0f32, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let positions: Vec<f32> = corners.iter().flat_map(|c| [c[0], c[1], 0.0]).collect();
    let pos = doc.add(&floats(&positions), 4, "VEC3", 5126);
    doc.accessors[pos]["min"] = json!([0.0, 0.0, 0.0]);
    doc.accessors[pos]["max"] = json!([1.0, 1.0, 0.0]);
    let uv = doc.add(&floats(corners.as_flattened()), 4, "VEC2", 5126);
    let idx: Vec<u8> = [0u32, 1, 2, 0, 2, 3]
        .iter()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let indices = doc.add(&idx, 6, "SCALAR", 5125);
    let mut attributes = serde_json::Map::new();
    attributes.insert("POSITION".into(), json!(pos));
    attributes.insert("TEXCOORD_0".into(), json!(uv));
    let mut rest = json!({
        "images": [{"uri": data_uri("image/png", &red_png())}],
        "textures": [{"source": 0}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
    });
    edit(&mut doc, &mut attributes, &mut rest);
    let mut out = json!({
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": doc.buf.len(),
                     "uri": data_uri("application/octet-stream", &doc.buf)}],
        "bufferViews": doc.views,
        "accessors": doc.accessors,
        "meshes": [{"primitives": [{"attributes": attributes, "indices": indices,
                                    "material": 0}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0,
    });
    if let (Some(o), Some(r)) = (out.as_object_mut(), rest.as_object()) {
        o.extend(r.clone());
    }
    out.to_string()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap_or_else(|e| panic!("{e}"));
    p
}

/// Converts the shape of `path` and reads and samples its appearance; the appearance.
fn convert(path: &Path) -> Result<Appearance, Box<dyn std::error::Error>> {
    let loaded = sparcubes::io::load(path)?;
    let cubes = sparcubes::convert(&loaded.mesh, &Params::with_resolution(16))?.cubes;
    let bytes = std::fs::read(path)?;
    let appearance = materials::read(&bytes, path, Buffers::Folder)?;
    let cells = sample(&cubes, &appearance);
    assert_eq!(cells.base_color.len(), cubes.cells.len());
    Ok(appearance)
}

/// Asserts that some entry of what was not read contains every one of `words`.
fn assert_named(app: &Appearance, words: &[&str]) {
    let not_read = &app.facts.not_read;
    assert!(
        not_read.iter().any(|n| words.iter().all(|w| n.contains(w))),
        "{words:?} not in {not_read:?}"
    );
}

#[test]
fn a_colour_accessor_of_a_type_colours_cannot_have_is_named_not_a_panic() -> TestResult {
    let dir = tempfile::tempdir()?;
    // (type, component type, bytes per element): a scalar float, two bytes, four u32s.
    let cases = [("SCALAR", 5126, 4), ("VEC2", 5121, 2), ("VEC4", 5125, 16)];
    for (k, (kind, ctype, size)) in cases.into_iter().enumerate() {
        let text = quad(|doc, attributes, _| {
            let colours = doc.add(&vec![200; 4 * size], 4, kind, ctype);
            attributes.insert("COLOR_0".into(), json!(colours));
        });
        let app = convert(&write(dir.path(), &format!("colour{k}.gltf"), &text))?;
        assert_named(&app, &["COLOR_0", kind]);
        assert!(!app.facts.vertex_colors, "case {kind}");
        // The texture is still read.
        assert_eq!(app.facts.textures, 1, "case {kind}");
    }
    Ok(())
}

#[test]
fn coordinates_of_a_component_type_they_cannot_have_are_named_not_a_panic() -> TestResult {
    let dir = tempfile::tempdir()?;
    let text = quad(|doc, attributes, _| {
        let uv = doc.add(&[0; 32], 4, "VEC2", 5125);
        attributes.insert("TEXCOORD_0".into(), json!(uv));
    });
    let app = convert(&write(dir.path(), "uv.gltf", &text))?;
    assert_named(&app, &["TEXCOORD_0"]);
    Ok(())
}

#[test]
fn an_image_without_a_uri_or_a_buffer_view_is_named_not_a_panic() -> TestResult {
    let dir = tempfile::tempdir()?;
    let text = quad(|doc, _, rest| {
        let view = doc.view(&red_png());
        // Image 0 has neither; image 1 a buffer view without the `mimeType` glTF requires
        // (read all the same: PNG and JPEG are told apart by their signatures).
        rest["images"] = json!([{"name": "nothing"}, {"bufferView": view}]);
        rest["textures"] = json!([{"source": 0}, {"source": 1}]);
        rest["materials"] = json!([{"pbrMetallicRoughness": {
            "baseColorTexture": {"index": 0}, "metallicRoughnessTexture": {"index": 1}}}]);
    });
    let app = convert(&write(dir.path(), "no_source.gltf", &text))?;
    assert_named(&app, &["image 0", "neither"]);
    assert!(
        !app.facts.not_read.iter().any(|n| n.contains("image 1")),
        "{:?}",
        app.facts.not_read
    );
    assert_eq!(app.facts.textures, 1);
    Ok(())
}

#[test]
fn indices_of_a_float_type_keep_the_shape_and_name_the_appearance_not_read() -> TestResult {
    let dir = tempfile::tempdir()?;
    let text = quad(|doc, _, _| {
        let idx = floats(&[0.0, 1.0, 2.0, 0.0, 2.0, 3.0]);
        let indices = doc.add(&idx, 6, "SCALAR", 5126);
        // The quad's own indices accessor is the third; point it at the float one.
        doc.accessors.swap(2, indices);
    });
    let app = convert(&write(dir.path(), "float_indices.gltf", &text))?;
    assert_named(&app, &["indices", "SCALAR of FLOAT"]);
    assert!(app.surface.triangles.is_empty());
    Ok(())
}

#[test]
fn a_texture_on_a_coordinate_set_that_is_not_read_is_named_and_not_counted() -> TestResult {
    let dir = tempfile::tempdir()?;
    // texCoord 9 (TEXCOORD_9 is never read), and texCoord 1 on a primitive with set 0 alone.
    for (set, name) in [(9, "TEXCOORD_9"), (1, "TEXCOORD_1")] {
        let text = quad(|_, _, rest| {
            rest["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"] =
                json!(set);
        });
        let app = convert(&write(dir.path(), &format!("set{set}.gltf"), &text))?;
        assert_named(&app, &[name]);
        assert_eq!(app.facts.textures, 0, "set {set}");
        assert!(!app.facts.textured(), "set {set}");
    }
    Ok(())
}

#[test]
fn coordinates_past_their_buffer_view_are_named_and_the_texture_not_counted() -> TestResult {
    let dir = tempfile::tempdir()?;
    let text = quad(|doc, _, _| {
        // TEXCOORD_0's view holds 4 coordinates; its accessor claims 8.
        doc.accessors[1]["count"] = json!(8);
    });
    let app = convert(&write(dir.path(), "past.gltf", &text))?;
    assert_named(&app, &["TEXCOORD_0", "run past its buffer view"]);
    assert_named(&app, &["has no TEXCOORD_0", "not sampled"]);
    assert!(!app.facts.textured());
    Ok(())
}

#[test]
fn an_image_named_by_many_entries_is_decoded_once_and_unsampled_ones_not_at_all() -> TestResult {
    let dir = tempfile::tempdir()?;
    std::fs::write(dir.path().join("t.png"), red_png())?;
    let text = quad(|_, _, rest| {
        // Twelve entries of one file (as `./t.png` and `t.png`), and one of a file that is
        // not there, read only by a material no triangle uses.
        let mut images: Vec<Value> = (0..12)
            .map(|i| json!({"uri": if i % 2 == 0 { "t.png" } else { "./t.png" }}))
            .collect();
        images.push(json!({"uri": "absent.png"}));
        rest["images"] = json!(images);
        rest["textures"] = json!((0..13).map(|i| json!({"source": i})).collect::<Vec<_>>());
        rest["materials"] = json!([
            {"pbrMetallicRoughness": {"baseColorTexture": {"index": 3},
                                      "metallicRoughnessTexture": {"index": 8}}},
            {"pbrMetallicRoughness": {"baseColorTexture": {"index": 12}}},
        ]);
    });
    let app = convert(&write(dir.path(), "twelve.gltf", &text))?;
    let decoded = app.images.iter().filter(|i| i.is_some()).count();
    assert_eq!(decoded, 1, "{} images decoded", decoded);
    assert_eq!(app.facts.textures, 1);
    assert!(app.facts.not_read.is_empty(), "{:?}", app.facts.not_read);
    // Both of the material's textures read the one decoded image.
    let m = &app.materials[0];
    let base = m.base_color_map.map(|t| t.image);
    let mr = m.roughness_map.map(|t| t.texture.image);
    assert!(base.is_some() && base == mr, "{base:?} {mr:?}");
    Ok(())
}
