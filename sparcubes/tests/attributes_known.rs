//! Appearance sampled at the active cells of generated textured meshes whose answers are known:
//! a cube with six flat colours from one atlas, a vertex-coloured PLY, an OBJ whose MTL has
//! `Kd` only, an alpha-masked quad, `KHR_texture_transform`, two UV sets, a UV sphere with a
//! gradient texture; and bad input
//! (truncated PNG, missing image, huge image, 1×1 texture, UVs far outside [0, 1], a texture
//! index past the end, a corrupt JPEG), which converts with the problem named or fails with a
//! clear error.

use base64::Engine as _;
use serde_json::{json, Value};
use sparcubes::attributes::{sample, CellAttributes};
use sparcubes::io::Buffers;
use sparcubes::materials::{self, Appearance};
use sparcubes::{Params, SparseCubes};
use std::path::{Path, PathBuf};

#[path = "support/barycentric.rs"]
mod barycentric;

type TestResult = Result<(), Box<dyn std::error::Error>>;

/// A PNG of `w × h` RGBA pixels from `pixel(x, y)`.
fn png(w: u32, h: u32, pixel: impl Fn(u32, u32) -> [u8; 4]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, w, h);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    let mut data = Vec::new();
    for y in 0..h {
        for x in 0..w {
            data.extend(pixel(x, y));
        }
    }
    match enc.write_header() {
        Ok(mut writer) => writer
            .write_image_data(&data)
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

/// A glTF primitive's data: positions, optional texture coordinate sets, triangles.
struct Prim {
    positions: Vec<[f32; 3]>,
    uv: Vec<Vec<[f32; 2]>>,
    triangles: Vec<[u32; 3]>,
}

/// A `.gltf` document with one primitive of `prim`, the material `material` and images given
/// by URI, its buffer embedded.
fn gltf(prim: &Prim, material: Value, images: &[String], samplers: Value) -> String {
    let mut buf: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut attributes = serde_json::Map::new();
    let mut add = |bytes: Vec<u8>, count: usize, kind: &str, ctype: u32, extra: Value| {
        views.push(json!({"buffer": 0, "byteOffset": buf.len(), "byteLength": bytes.len()}));
        let mut acc = json!({"bufferView": views.len() - 1, "componentType": ctype,
                              "count": count, "type": kind});
        if let (Some(a), Some(e)) = (acc.as_object_mut(), extra.as_object()) {
            a.extend(e.clone());
        }
        accessors.push(acc);
        buf.extend(bytes);
        accessors.len() - 1
    };
    let floats = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let (lo, hi) = bounds(&prim.positions);
    let pos = add(
        floats(prim.positions.as_flattened()),
        prim.positions.len(),
        "VEC3",
        5126,
        json!({"min": lo, "max": hi}),
    );
    attributes.insert("POSITION".into(), json!(pos));
    for (s, uv) in prim.uv.iter().enumerate() {
        let a = add(floats(uv.as_flattened()), uv.len(), "VEC2", 5126, json!({}));
        attributes.insert(format!("TEXCOORD_{s}"), json!(a));
    }
    let idx: Vec<u8> = prim
        .triangles
        .as_flattened()
        .iter()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let indices = add(idx, prim.triangles.len() * 3, "SCALAR", 5125, json!({}));
    let textures: Vec<Value> = (0..images.len())
        .map(|i| json!({"source": i, "sampler": 0}))
        .collect();
    json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_texture_transform"],
        "buffers": [{"byteLength": buf.len(), "uri": data_uri("application/octet-stream", &buf)}],
        "bufferViews": views,
        "accessors": accessors,
        "images": images.iter().map(|u| json!({"uri": u})).collect::<Vec<_>>(),
        "samplers": [samplers],
        "textures": textures,
        "materials": [material],
        "meshes": [{"primitives": [{"attributes": attributes, "indices": indices, "material": 0}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0,
    })
    .to_string()
}

fn bounds(p: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for q in p {
        for a in 0..3 {
            lo[a] = lo[a].min(q[a]);
            hi[a] = hi[a].max(q[a]);
        }
    }
    (lo, hi)
}

/// The six faces of the cube [-1, 1]³ as quads (outward), each with its own four corners and
/// the texture coordinates `uv(face, corner)`; corners run (0,0), (1,0), (1,1), (0,1) in the
/// face's own (s, t).
fn cube(uv: impl Fn(usize, [f32; 2]) -> [f32; 2]) -> Prim {
    // (normal axis, sign)
    let faces = [
        (0, 1.0),
        (0, -1.0),
        (1, 1.0),
        (1, -1.0),
        (2, 1.0),
        (2, -1.0),
    ];
    let mut prim = Prim {
        positions: Vec::new(),
        uv: vec![Vec::new()],
        triangles: Vec::new(),
    };
    for (f, &(axis, sign)) in faces.iter().enumerate() {
        let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
        let base = prim.positions.len() as u32;
        for st in [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]] {
            let mut p = [0.0f32; 3];
            p[axis] = sign;
            p[a1] = 2.0 * st[0] - 1.0;
            p[a2] = 2.0 * st[1] - 1.0;
            prim.positions.push(p);
            prim.uv[0].push(uv(f, st));
        }
        let (q0, q1) = if sign > 0.0 {
            ([0, 1, 2], [0, 2, 3])
        } else {
            ([0, 2, 1], [0, 3, 2])
        };
        prim.triangles.push(q0.map(|k| base + k));
        prim.triangles.push(q1.map(|k| base + k));
    }
    prim
}

/// A converted file: its cubes, appearance and attributes.
struct Sampled {
    cubes: SparseCubes,
    appearance: Appearance,
    cells: CellAttributes,
}

fn convert(path: &Path, n: u32) -> Result<Sampled, Box<dyn std::error::Error>> {
    let loaded = sparcubes::io::load(path)?;
    let cubes = sparcubes::convert(&loaded.mesh, &Params::with_resolution(n))?.cubes;
    let bytes = std::fs::read(path)?;
    let appearance = materials::read(&bytes, path, Buffers::Folder)?;
    let cells = sample(&cubes, &appearance);
    assert_eq!(cells.base_color.len(), cubes.cells.len());
    Ok(Sampled {
        cubes,
        appearance,
        cells,
    })
}

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap_or_else(|e| panic!("{e}"));
    p
}

/// The centre of cell `i` in the source frame.
fn centre(s: &Sampled, i: usize) -> [f64; 3] {
    let c = s.cubes.cells[i].map(|x| x as f64 + 0.5);
    s.cubes.normalization.grid_to_source(c, s.cubes.resolution)
}

/// For a cell of the cube [-1, 1]³ whose centre is clearly nearer one face than any other (by
/// `margin` source units), that face's number (as in [`cube`]).
fn cube_face(p: [f64; 3], margin: f64) -> Option<usize> {
    let mut d: Vec<(f64, usize)> = (0..6)
        .map(|f| {
            let (axis, sign) = (f / 2, if f % 2 == 0 { 1.0 } else { -1.0 });
            ((p[axis] - sign).abs(), f)
        })
        .collect();
    d.sort_by(|a, b| a.0.total_cmp(&b.0));
    (d[1].0 - d[0].0 > margin).then_some(d[0].1)
}

const SIX: [[u8; 4]; 6] = [
    [230, 25, 75, 255],
    [60, 180, 75, 255],
    [255, 225, 25, 255],
    [0, 130, 200, 255],
    [245, 130, 48, 255],
    [145, 30, 180, 255],
];

#[test]
fn a_cube_with_six_colours_from_one_atlas_gets_each_face_its_colour() -> TestResult {
    let dir = tempfile::tempdir()?;
    // A 192 × 128 atlas of 3 × 2 tiles of 64 px; each face maps into the middle of its tile.
    let atlas = png(192, 128, |x, y| SIX[(y / 64 * 3 + x / 64) as usize]);
    let prim = cube(|f, st| {
        let (tx, ty) = ((f % 3) as f32, (f / 3) as f32);
        [
            (tx * 64.0 + 8.0 + 48.0 * st[0]) / 192.0,
            (ty * 64.0 + 8.0 + 48.0 * st[1]) / 128.0,
        ]
    });
    let material = json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                          "metallicFactor": 0.25, "roughnessFactor": 0.75}});
    let doc = gltf(&prim, material, &[data_uri("image/png", &atlas)], json!({}));
    let s = convert(&write(dir.path(), "cube.gltf", doc), 32)?;
    let facts = &s.appearance.facts;
    assert_eq!((facts.textures, facts.largest_texture), (1, 192));
    assert!(facts.not_read.is_empty(), "{:?}", facts.not_read);
    let margin = 4.0 / 32.0;
    let mut checked = [0usize; 6];
    for i in 0..s.cubes.cells.len() {
        let Some(f) = cube_face(centre(&s, i), margin) else {
            continue;
        };
        let want = &SIX[f][..3];
        let got = s.cells.base_color[i];
        let err = (0..3).map(|c| got[c].abs_diff(want[c])).max().unwrap_or(0);
        assert!(err <= 1, "cell {i} on face {f}: {got:?}, want {want:?}");
        assert_eq!((s.cells.metallic[i], s.cells.roughness[i]), (64, 191));
        assert_eq!(s.cells.alpha[i], 255);
        checked[f] += 1;
    }
    assert!(checked.iter().all(|&k| k > 100), "{checked:?}");
    Ok(())
}

#[test]
fn an_edge_cell_mixes_its_faces_in_linear_light() -> TestResult {
    // Two faces, black and white: a cell on their edge holds about half of each, which is
    // 0.5 in linear light, stored as sRGB byte 188, never the 128 of averaging bytes.
    let dir = tempfile::tempdir()?;
    let atlas = png(2, 1, |x, _| if x == 0 { [0, 0, 0, 255] } else { [255; 4] });
    let prim = cube(|f, st| [if f == 0 { 0.25 } else { 0.75 }, 0.5 + 0.0 * st[0]]);
    let material = json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}});
    let sampler = json!({"magFilter": 9728, "wrapS": 33071, "wrapT": 33071});
    let doc = gltf(&prim, material, &[data_uri("image/png", &atlas)], sampler);
    let s = convert(&write(dir.path(), "edge.gltf", doc), 32)?;
    let h = 1.0 / (s.cubes.normalization.scale * 32.0);
    let mut mixed = 0;
    for i in 0..s.cubes.cells.len() {
        let p = centre(&s, i);
        // The cells the edge x = y = 1 runs through (away from the cube's corners): face 0
        // (x = 1, black) covers (1 − y_min)·h of it, face 2 (y = 1, white) (1 − x_min)·h.
        let (x0, y0) = (p[0] - h / 2.0, p[1] - h / 2.0);
        if !(x0 < 1.0 && x0 + h > 1.0 && y0 < 1.0 && y0 + h > 1.0 && p[2].abs() < 0.8) {
            continue;
        }
        let white = (1.0 - x0) / ((1.0 - x0) + (1.0 - y0));
        let want = (sparcubes::attributes::mips::linear_to_srgb(white as f32) * 255.0).round();
        let got = s.cells.base_color[i][0] as f32;
        assert!(
            (got - want).abs() <= 2.0,
            "edge cell at {p:?}: {got}, want {want} (linear {white:.3})"
        );
        mixed += 1;
    }
    assert!(mixed > 10, "{mixed} cells on the edge");
    Ok(())
}

#[test]
fn a_vertex_coloured_ply_gets_its_colours() -> TestResult {
    // The cube with x = −1 corners red and x = +1 corners blue: the x faces are flat red and
    // blue, the others a ramp in linear light along x.
    let dir = tempfile::tempdir()?;
    let mut text = String::from(
        "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\n\
         property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
         element face 6\nproperty list uchar int vertex_indices\nend_header\n",
    );
    for k in 0..8 {
        let p = [k & 1, (k >> 1) & 1, (k >> 2) & 1].map(|b: i32| 2 * b - 1);
        let c = if p[0] < 0 { "255 0 0" } else { "0 0 255" };
        text.push_str(&format!("{} {} {} {c}\n", p[0], p[1], p[2]));
    }
    for f in [
        "0 2 6 4", "1 5 7 3", "0 4 5 1", "2 3 7 6", "0 1 3 2", "4 6 7 5",
    ] {
        text.push_str(&format!("4 {f}\n"));
    }
    let s = convert(&write(dir.path(), "colored.ply", text), 32)?;
    assert!(s.appearance.facts.vertex_colors);
    let lin = |b: f64| materials::srgb_to_linear(b as f32) as f64;
    let enc = |l: f64| {
        let s = sparcubes::attributes::mips::linear_to_srgb(l as f32) as f64;
        (s * 255.0).round()
    };
    let (mut flat, mut ramp) = (0, 0);
    for i in 0..s.cubes.cells.len() {
        let p = centre(&s, i);
        let Some(f) = cube_face(p, 4.0 / 32.0) else {
            continue;
        };
        let got = s.cells.base_color[i].map(f64::from);
        let t = ((p[0] + 1.0) / 2.0).clamp(0.0, 1.0);
        let want = match f {
            0 => [0.0f64, 0.0, 255.0],
            1 => [255.0, 0.0, 0.0],
            _ => [enc((1.0 - t) * lin(1.0)), 0.0, enc(t * lin(1.0))],
        };
        // A cell's mean is the ramp at its piece's centroid, within half a cell of its
        // centre along x: 1/60 of the ramp, at most ~9 sRGB steps where it is steepest.
        let tol = if f < 2 { 1.0 } else { 10.0 };
        for c in 0..3 {
            assert!(
                (got[c] - want[c]).abs() <= tol,
                "cell at {p:?} face {f}: {got:?} vs {want:?}"
            );
        }
        if f < 2 {
            flat += 1;
        } else {
            ramp += 1;
        }
    }
    assert!(flat > 200 && ramp > 800, "{flat} {ramp}");
    Ok(())
}

#[test]
fn an_obj_with_kd_only_gets_its_material_colours() -> TestResult {
    let dir = tempfile::tempdir()?;
    write(
        dir.path(),
        "m.mtl",
        "newmtl top\nKd 0.2 0.6 0.4\nPm 0.5\nPr 0.1\nnewmtl rest\nKd 0.8 0.2 0.2\nd 1\n",
    );
    let mut obj = String::from("mtllib m.mtl\n");
    for k in 0..8 {
        let p = [k & 1, (k >> 1) & 1, (k >> 2) & 1].map(|b: i32| 2 * b - 1);
        obj.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
    }
    obj.push_str("usemtl rest\nf 1 3 7 5\nf 2 6 8 4\nf 1 5 6 2\nf 3 4 8 7\nf 1 2 4 3\n");
    obj.push_str("usemtl top\nf 5 7 8 6\n");
    let s = convert(&write(dir.path(), "kd.obj", obj), 32)?;
    assert_eq!(s.appearance.facts.materials, 2);
    let mut seen = [0; 2];
    for i in 0..s.cubes.cells.len() {
        let Some(f) = cube_face(centre(&s, i), 4.0 / 32.0) else {
            continue;
        };
        let (want, m, r) = if f == 4 {
            ([51, 153, 102], 128, 26)
        } else {
            // Ns absent: the default roughness 0.5.
            ([204, 51, 51], 0, 128)
        };
        let got = s.cells.base_color[i];
        assert!(
            (0..3).all(|c| got[c].abs_diff(want[c]) <= 1),
            "{got:?} vs {want:?}"
        );
        assert_eq!((s.cells.metallic[i], s.cells.roughness[i]), (m, r));
        seen[usize::from(f == 4)] += 1;
    }
    assert!(seen[0] > 0 && seen[1] > 0);
    Ok(())
}

/// The unit quad in the z = 0 plane, (s, t) = (x, y) in [0, 1]², with texture coordinates
/// `uv(s, t)` per set.
fn quad(sets: &[&dyn Fn([f32; 2]) -> [f32; 2]]) -> Prim {
    let st = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    Prim {
        positions: st.iter().map(|p| [p[0], p[1], 0.0]).collect(),
        uv: sets
            .iter()
            .map(|f| st.iter().map(|&p| f(p)).collect())
            .collect(),
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// The value of every cell whose centre projects onto the quad at (s, t) with `keep(s, t)`.
fn quad_cells(s: &Sampled, keep: impl Fn(f64, f64) -> bool) -> Vec<usize> {
    (0..s.cubes.cells.len())
        .filter(|&i| {
            let p = centre(s, i);
            keep(p[0], p[1])
        })
        .collect()
}

/// Four 32 px quadrants: red top left, green top right, blue bottom left, white bottom right
/// (rows from the top, glTF's v down).
fn quadrants() -> Vec<u8> {
    png(64, 64, |x, y| match (x / 32, y / 32) {
        (0, 0) => [255, 0, 0, 255],
        (1, 0) => [0, 255, 0, 255],
        (0, _) => [0, 0, 255, 255],
        _ => [255, 255, 255, 255],
    })
}

#[test]
fn an_alpha_masked_quad_is_transparent_where_the_mask_is() -> TestResult {
    let dir = tempfile::tempdir()?;
    let mask = png(64, 64, |x, _| {
        [200, 200, 200, if x < 32 { 40 } else { 220 }]
    });
    let material = json!({"alphaMode": "MASK", "alphaCutoff": 0.5,
                          "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}});
    let doc = gltf(
        &quad(&[&|p| p]),
        material,
        &[data_uri("image/png", &mask)],
        json!({}),
    );
    let s = convert(&write(dir.path(), "mask.gltf", doc), 32)?;
    assert_eq!(s.appearance.facts.alpha_modes, ["MASK"]);
    let left = quad_cells(&s, |x, y| x < 0.4 && (0.1..0.9).contains(&y) && x > 0.05);
    let right = quad_cells(&s, |x, y| x > 0.6 && (0.1..0.9).contains(&y) && x < 0.95);
    assert!(left.len() > 20 && right.len() > 20);
    assert!(left.iter().all(|&i| s.cells.alpha[i] == 0));
    assert!(right.iter().all(|&i| s.cells.alpha[i] == 255));
    // The sheet's thin shell has a far wall no triangle crosses: it takes the nearest values.
    assert!(s.cells.nearest_cells > 0);
    Ok(())
}

#[test]
fn khr_texture_transform_picks_the_transformed_region() -> TestResult {
    let dir = tempfile::tempdir()?;
    let image = data_uri("image/png", &quadrants());
    let cases = [
        // Scale ½ and offset (½, 0): [0.5, 1] × [0, 0.5], the top right (green).
        (
            json!({"offset": [0.5, 0.0], "scale": [0.5, 0.5]}),
            [0, 255, 0],
        ),
        // A quarter turn: (u, v) ↦ (v, 1 − u) then scaled by ½ about the origin: the lower
        // left quadrant of the quad at (s, t) = (0.25, 0.25) reads (0.125, 0.375) — red.
        (
            json!({"rotation": std::f64::consts::FRAC_PI_2, "offset": [0.0, 0.5],
                "scale": [0.5, 0.5]}),
            [255, 0, 0],
        ),
    ];
    for (k, (transform, want)) in cases.into_iter().enumerate() {
        let material = json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0,
                              "extensions": {"KHR_texture_transform": transform}}}});
        let doc = gltf(
            &quad(&[&|p| p]),
            material,
            std::slice::from_ref(&image),
            json!({}),
        );
        let s = convert(&write(dir.path(), &format!("t{k}.gltf"), doc), 32)?;
        let cells = quad_cells(&s, |x, y| {
            (0.1..0.4).contains(&x) && (0.1..0.4).contains(&y)
        });
        assert!(cells.len() > 10);
        for i in cells {
            let got = s.cells.base_color[i];
            assert!(
                (0..3).all(|c| got[c].abs_diff(want[c]) <= 2),
                "case {k}: {got:?} vs {want:?}"
            );
        }
    }
    Ok(())
}

#[test]
fn a_texture_reads_the_coordinate_set_it_names() -> TestResult {
    let dir = tempfile::tempdir()?;
    let image = data_uri("image/png", &quadrants());
    // Set 0 maps the quad into the red quadrant, set 1 into the white one.
    let set0 = |p: [f32; 2]| [0.1 + 0.3 * p[0], 0.1 + 0.3 * p[1]];
    let set1 = |p: [f32; 2]| [0.6 + 0.3 * p[0], 0.6 + 0.3 * p[1]];
    for (set, want) in [(0, [255, 0, 0]), (1, [255, 255, 255])] {
        let material =
            json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": set}}});
        let doc = gltf(
            &quad(&[&set0, &set1]),
            material,
            std::slice::from_ref(&image),
            json!({}),
        );
        let s = convert(&write(dir.path(), &format!("set{set}.gltf"), doc), 32)?;
        let cells = quad_cells(&s, |x, y| {
            (0.1..0.9).contains(&x) && (0.1..0.9).contains(&y)
        });
        assert!(cells.len() > 50);
        for i in cells {
            assert_eq!(s.cells.base_color[i], want, "set {set}");
        }
    }
    Ok(())
}

/// The quad with a base colour texture at `uri` (or a JPEG/PNG bytes file beside it), factor
/// (0.5, 0.5, 0.5) linear; converted.
fn textured_quad(
    dir: &Path,
    name: &str,
    uri: &str,
    uv: &dyn Fn([f32; 2]) -> [f32; 2],
) -> Result<Sampled, Box<dyn std::error::Error>> {
    let material = json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                          "baseColorFactor": [0.5, 0.5, 0.5, 1.0]}});
    let doc = gltf(&quad(&[uv]), material, &[uri.to_string()], json!({}));
    convert(&write(dir, name, doc), 16)
}

/// Asserts every cell has base colour `want` and the item names `problem` as not read.
fn assert_named(s: &Sampled, problem: &str, want: [u8; 3]) {
    let not_read = &s.appearance.facts.not_read;
    assert!(
        not_read.iter().any(|n| n.contains(problem)),
        "{problem:?} not in {not_read:?}"
    );
    assert!(
        s.cells.base_color.iter().all(|&c| c == want),
        "{:?}",
        &s.cells.base_color[..3]
    );
}

#[test]
fn bad_textures_convert_with_the_problem_named() -> TestResult {
    let dir = tempfile::tempdir()?;
    let good = png(16, 16, |_, _| [255, 0, 0, 255]);
    write(dir.path(), "truncated.png", &good[..good.len() / 2]);
    let mut huge = png(1, 1, |_, _| [0; 4]);
    huge[16..24].copy_from_slice(&[0, 0, 64, 0, 0, 0, 64, 0]); // 16384 × 16384
    write(dir.path(), "huge.png", &huge);
    write(
        dir.path(),
        "corrupt.jpg",
        [0xFF, 0xD8, 0xFF, 0xE0, 0, 16, b'J', b'F', b'I', b'F', 0, 1],
    );
    // The factor alone: 0.5 linear, sRGB byte 188.
    let factor = [188, 188, 188];
    let cases = [
        ("truncated.png", "PNG:"),
        ("missing.png", "missing.png"),
        ("huge.png", "PNG:"),
        ("corrupt.jpg", "JPEG:"),
    ];
    for (k, (file, problem)) in cases.into_iter().enumerate() {
        let s = textured_quad(dir.path(), &format!("bad{k}.gltf"), file, &|p| p)?;
        assert_named(&s, problem, factor);
        assert_eq!(s.appearance.facts.textures, 0);
    }
    Ok(())
}

#[test]
fn a_huge_png_is_refused_by_its_size() -> TestResult {
    let mut bytes = png(1, 1, |_, _| [0; 4]);
    bytes[16..24].copy_from_slice(&[0, 0, 64, 0, 0, 0, 64, 0]);
    let mut crc = 0xFFFF_FFFFu32;
    for &b in &bytes[12..29] {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                0xEDB8_8320 ^ (crc >> 1)
            } else {
                crc >> 1
            };
        }
    }
    bytes[29..33].copy_from_slice(&(!crc).to_be_bytes());
    let err = materials::image::decode(&bytes).err().unwrap_or_default();
    assert!(
        err.contains("16384×16384") && err.contains("limit"),
        "{err}"
    );
    Ok(())
}

#[test]
fn a_one_pixel_texture_and_far_uvs_read_plainly() -> TestResult {
    let dir = tempfile::tempdir()?;
    let one = png(1, 1, |_, _| [255, 255, 255, 255]);
    write(dir.path(), "one.png", &one);
    // White × 0.5: 188 everywhere.
    let s = textured_quad(dir.path(), "one.gltf", "one.png", &|p| p)?;
    assert!(s.cells.base_color.iter().all(|&c| c == [188; 3]));
    assert_eq!(s.appearance.facts.largest_texture, 1);
    // UVs a million tiles away repeat the texture as near the origin.
    write(dir.path(), "q.png", quadrants());
    let near = textured_quad(dir.path(), "near.gltf", "q.png", &|p| {
        [0.1 + 0.3 * p[0], 0.1 + 0.3 * p[1]]
    })?;
    let far = textured_quad(dir.path(), "far.gltf", "q.png", &|p| {
        [1.0e6 + 0.1 + 0.3 * p[0], -1.0e6 + 0.1 + 0.3 * p[1]]
    })?;
    assert_eq!(near.cells, far.cells);
    assert!(near.cells.base_color.iter().all(|&c| c == [188, 0, 0]));
    Ok(())
}

#[test]
fn a_texture_index_past_the_end_fails_with_a_clear_error() -> TestResult {
    let dir = tempfile::tempdir()?;
    let material = json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 5}}});
    let doc = gltf(
        &quad(&[&|p| p]),
        material,
        &[data_uri("image/png", &quadrants())],
        json!({}),
    );
    let path = write(dir.path(), "past.gltf", doc);
    let err = materials::read(&std::fs::read(&path)?, &path, Buffers::Folder)
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(
        err.contains("past.gltf") && err.contains("baseColorTexture.index: Index out of bounds"),
        "{err}"
    );
    Ok(())
}

#[test]
fn attributes_do_not_depend_on_the_thread_count() -> TestResult {
    let dir = tempfile::tempdir()?;
    let atlas = png(192, 128, |x, y| SIX[(y / 64 * 3 + x / 64) as usize]);
    let prim = cube(|f, st| {
        [
            ((f % 3) as f32 + st[0]) / 3.0,
            ((f / 3) as f32 + st[1]) / 2.0,
        ]
    });
    let material = json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}});
    let doc = gltf(&prim, material, &[data_uri("image/png", &atlas)], json!({}));
    let path = write(dir.path(), "cube.gltf", doc);
    // At 256³ the cube's cells are several parts (attributes::parts), sampled in parallel.
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let a = one.install(|| convert(&path, 256).map_err(|e| e.to_string()))?;
    let four = rayon::ThreadPoolBuilder::new().num_threads(4).build()?;
    let b = four.install(|| convert(&path, 256).map_err(|e| e.to_string()))?;
    let rows = a.cells.base_color.len();
    assert!(
        rows > 3 * sparcubes::attributes::parts::ROWS_PER_PART,
        "{rows} rows"
    );
    assert_eq!(a.cells, b.cells);
    Ok(())
}

/// The base colour an independent reference gives cell `i`: the source surface's closest point
/// to the cell's centre, its texture coordinates, the nearest texel of the full-size image,
/// times the factor (as sRGB bytes).
fn reference_color(
    s: &Sampled,
    index: &sparcubes::queries::closest::TriangleIndex,
    i: usize,
) -> [u8; 3] {
    let app = &s.appearance;
    let c = s.cubes.cells[i].map(|x| x as f64 + 0.5);
    let Some(hit) = index.closest(c) else {
        return [0; 3];
    };
    let t = hit.triangle as usize;
    let n = s.cubes.resolution;
    let corners = app.surface.triangles[t].map(|v| {
        let p = app.surface.positions[v as usize].map(f64::from);
        s.cubes.normalization.source_to_grid(p, n)
    });
    let b = barycentric::barycentric_by_areas(hit.point, corners);
    let m = &app.materials[app.surface.material[t] as usize];
    let mut rgb = [m.base_color[0], m.base_color[1], m.base_color[2]].map(f64::from);
    if let (Some(tex), Some(uv)) = (m.base_color_map, app.surface.uv[0].at(t)) {
        if let Some(Some(image)) = app.images.get(tex.image) {
            let u: f64 = (0..3).map(|k| b[k] * uv[k][0] as f64).sum();
            let v: f64 = (0..3).map(|k| b[k] * uv[k][1] as f64).sum();
            let (w, h) = (image.width as f64, image.height as f64);
            let x = ((u.rem_euclid(1.0) * w) as usize).min(image.width as usize - 1);
            let y = ((v.rem_euclid(1.0) * h) as usize).min(image.height as usize - 1);
            let texel = image.pixels[y * image.width as usize + x];
            for k in 0..3 {
                rgb[k] *= materials::srgb_to_linear(texel[k] as f32 / 255.0) as f64;
            }
        }
    }
    rgb.map(|l| (sparcubes::attributes::mips::linear_to_srgb(l as f32) * 255.0).round() as u8)
}

#[test]
fn a_real_textured_asset_agrees_with_an_independent_reference() -> TestResult {
    // The bar: against the closest source point's texel × factor, the per-cell error
    // (largest channel) has median ≤ 12/255 and 90th percentile ≤ 48/255.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/box_textured.glb");
    for n in [32, 96] {
        let s = convert(&path, n)?;
        assert_eq!(s.appearance.facts.textures, 1);
        let positions = s
            .appearance
            .surface
            .positions
            .iter()
            .map(|p| {
                s.cubes
                    .normalization
                    .source_to_grid(p.map(f64::from), n)
                    .map(|x| x as f32)
            })
            .collect();
        let mesh = sparcubes::TriMesh::new(positions, s.appearance.surface.triangles.clone());
        let index = sparcubes::queries::closest::TriangleIndex::new(&mesh);
        let mut errors: Vec<u8> = (0..s.cubes.cells.len())
            .map(|i| {
                let want = reference_color(&s, &index, i);
                let got = s.cells.base_color[i];
                (0..3).map(|c| got[c].abs_diff(want[c])).max().unwrap_or(0)
            })
            .collect();
        errors.sort_unstable();
        let (median, p90) = (errors[errors.len() / 2], errors[errors.len() * 9 / 10]);
        eprintln!("box_textured.glb at {n}³: per-cell error median {median}/255, p90 {p90}/255");
        assert!(
            median <= 12 && p90 <= 48,
            "at {n}³: median {median}, p90 {p90}"
        );
    }
    Ok(())
}

/// A UV sphere of radius 1 about the origin: `rings` bands of colatitude θ from the +y pole,
/// `segments` of longitude φ, a seam of repeated vertices at φ = 0 and 2π; texture
/// coordinates (u, v) = (φ / 2π, θ / π), so v runs from 0 at the top to 1 at the bottom, as
/// glTF's rows run. Triangles face outwards; the poles' degenerate ones are dropped at load.
fn uv_sphere(rings: u32, segments: u32) -> Prim {
    let mut prim = Prim {
        positions: Vec::new(),
        uv: vec![Vec::new()],
        triangles: Vec::new(),
    };
    for i in 0..=rings {
        for j in 0..=segments {
            let (u, v) = (j as f64 / segments as f64, i as f64 / rings as f64);
            let (theta, phi) = (v * std::f64::consts::PI, u * std::f64::consts::TAU);
            let p = [
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            ];
            prim.positions.push(p.map(|x| x as f32));
            prim.uv[0].push([u as f32, v as f32]);
        }
    }
    let at = |i: u32, j: u32| i * (segments + 1) + j;
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            prim.triangles.push([a, d, c]);
            prim.triangles.push([a, c, b]);
        }
    }
    prim
}

/// The analytic attributes of the UV sphere's cells: the area-weighted means over the
/// sphere's surface inside each cell (by a fine grid of (θ, φ) weighted by sin θ) of base
/// colour (red sRGB v, green 1 − v, in linear light) and of roughness v, as sRGB bytes and a
/// byte; `None` for a cell the sphere does not cross.
fn sphere_means(s: &Sampled) -> Vec<Option<([u8; 2], u8)>> {
    use sparcubes::colour::{linear_to_srgb, srgb_to_linear, to_byte};
    let (rings, segments) = (1500, 3000);
    let mut sums = vec![[0.0f64; 4]; s.cubes.cells.len()];
    for i in 0..rings {
        let v = (i as f64 + 0.5) / rings as f64;
        let theta = v * std::f64::consts::PI;
        let red = srgb_to_linear(v as f32) as f64;
        let green = srgb_to_linear(1.0 - v as f32) as f64;
        for j in 0..segments {
            let phi = (j as f64 + 0.5) / segments as f64 * std::f64::consts::TAU;
            let p = [
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            ];
            let g = s.cubes.normalization.source_to_grid(p, s.cubes.resolution);
            let key = g.map(|x| x.floor() as u16);
            if let Ok(row) = s.cubes.cells.binary_search(&key) {
                let w = theta.sin();
                let sum = &mut sums[row];
                sum[0] += w;
                sum[1] += w * red;
                sum[2] += w * green;
                sum[3] += w * v;
            }
        }
    }
    sums.iter()
        .map(|m| {
            let mean = |k: usize| (m[k] / m[0]) as f32;
            (m[0] > 0.0).then(|| {
                let rgb = [1, 2].map(|k| to_byte(linear_to_srgb(mean(k))));
                (rgb, to_byte(mean(3)))
            })
        })
        .collect()
}

#[test]
fn a_uv_sphere_with_a_gradient_texture_gets_the_analytic_colours() -> TestResult {
    // Base colour: red rises and green falls with v as sRGB (red = v, green = 1 − v, the
    // texel rows' centres on that ramp), blue is constant 128; roughness (green of the
    // metallic-roughness texture, linear data) = v, metallic (its blue) 0. The sampler clamps
    // v, so that the filter does not wrap the bottom row onto the top at the poles.
    let dir = tempfile::tempdir()?;
    let ramp = |y: u32| ((y as f64 + 0.5) / 256.0 * 255.0).round() as u8;
    let colour = png(4, 256, |_, y| [ramp(y), 255 - ramp(y), 128, 255]);
    let data = png(4, 256, |_, y| [0, ramp(y), 0, 255]);
    let material = json!({"pbrMetallicRoughness": {
        "baseColorTexture": {"index": 0}, "metallicRoughnessTexture": {"index": 1}}});
    let images = [data_uri("image/png", &colour), data_uri("image/png", &data)];
    let sampler = json!({"wrapS": 10497, "wrapT": 33071});
    let doc = gltf(&uv_sphere(96, 192), material, &images, sampler);
    let s = convert(&write(dir.path(), "sphere.gltf", doc), 64)?;
    assert_eq!(s.appearance.facts.textures, 2);
    let means = sphere_means(&s);
    let (mut worst, mut checked) = ([0u8; 4], 0);
    for (i, want) in means.iter().enumerate() {
        assert_eq!((s.cells.metallic[i], s.cells.alpha[i]), (0, 255));
        let Some(([red, green], roughness)) = *want else {
            continue; // the sphere does not cross it: a nearest-filled cell
        };
        let got = s.cells.base_color[i];
        let err = [
            got[0].abs_diff(red),
            got[1].abs_diff(green),
            got[2].abs_diff(128),
            s.cells.roughness[i].abs_diff(roughness),
        ];
        for k in 0..4 {
            worst[k] = worst[k].max(err[k]);
        }
        checked += 1;
    }
    eprintln!(
        "UV sphere at 64³, {checked} of {} cells crossed: worst error red {}, green {}, \
         blue {}, roughness {}",
        means.len(),
        worst[0],
        worst[1],
        worst[2],
        worst[3]
    );
    // What may differ from the analytic mean: the mesh's flat facets (96 × 192 of them, their
    // texture coordinates linear across each) against the round sphere, the filter over a
    // piece's footprint (exact on a ramp but for its clamped ends) and rounding: at most two
    // bytes; blue, constant, exact to a byte.
    assert!(
        checked * 10 > means.len() * 9,
        "{checked} of {}",
        means.len()
    );
    assert!(worst[0] <= 2 && worst[1] <= 2 && worst[3] <= 2, "{worst:?}");
    assert!(worst[2] <= 1, "{worst:?}");
    Ok(())
}
