//! Issue 43 item 4, "a person can look": `convert --attributes` and `show` of a job with
//! `[attributes]` write the output mesh in colour where the format holds colours (PLY, OBJ,
//! GLB), and say so where it does not (STL).

mod common;
use common::{ok, s, sparc3d};
use std::path::Path;

/// A cube whose eight vertices all carry one sRGB colour (an ASCII PLY with vertex colours).
fn coloured_cube(path: &Path, rgb: [u8; 3]) {
    let mut text = String::from(
        "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\n\
         property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
         element face 12\nproperty list uchar int vertex_indices\nend_header\n",
    );
    let (corners, faces) = common::boxed([1.0; 3], [0.0; 3]);
    for [x, y, z] in corners {
        text += &format!("{x} {y} {z} {} {} {}\n", rgb[0], rgb[1], rgb[2]);
    }
    for [a, b, c] in faces {
        text += &format!("3 {a} {b} {c}\n");
    }
    std::fs::write(path, text).unwrap_or_else(|e| panic!("{e}"));
}

/// The vertex colours of a binary PLY this project wrote: (red, green, blue, alpha) each.
fn ply_colours(path: &Path) -> Vec<[u8; 4]> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{e}"));
    let end = b"end_header\n";
    let at = bytes
        .windows(end.len())
        .position(|w| w == end)
        .unwrap_or_else(|| panic!("no PLY header in {}", path.display()));
    let header = String::from_utf8_lossy(&bytes[..at]);
    assert!(
        header.contains(
            "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n"
        ),
        "{header}"
    );
    let n: usize = header
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or_else(|| panic!("{header}"));
    let body = &bytes[at + end.len()..];
    (0..n)
        .map(|i| {
            let v = &body[16 * i + 12..16 * i + 16];
            [v[0], v[1], v[2], v[3]]
        })
        .collect()
}

#[test]
fn a_one_colour_cube_comes_out_in_that_colour_in_every_format_that_holds_colours() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let cube = dir.path().join("cube.ply");
    coloured_cube(&cube, [200, 30, 90]);
    let ply = dir.path().join("out.ply");
    ok(&[
        "convert",
        s(&cube),
        "-o",
        s(&ply),
        "--resolution",
        "32",
        "--attributes",
    ]);
    let colours = ply_colours(&ply);
    assert!(!colours.is_empty());
    // One colour averaged in linear light and back to sRGB bytes: within one step of it.
    for c in &colours {
        let off = (0..3)
            .map(|k| (i32::from(c[k]) - [200, 30, 90][k]).abs())
            .max();
        assert!(off <= Some(1) && c[3] == 255, "{c:?}");
    }

    let obj = dir.path().join("out.obj");
    ok(&[
        "convert",
        s(&cube),
        "-o",
        s(&obj),
        "--resolution",
        "32",
        "--attributes",
    ]);
    let text = std::fs::read_to_string(&obj).unwrap_or_else(|e| panic!("{e}"));
    let first = text
        .lines()
        .find(|l| l.starts_with("v "))
        .unwrap_or_default();
    let rgb: Vec<f32> = first
        .split(' ')
        .skip(4)
        .filter_map(|x| x.parse().ok())
        .collect();
    assert_eq!(rgb.len(), 3, "{first}");
    assert!((rgb[0] * 255.0 - 200.0).abs() <= 1.5, "{first}");

    let glb = dir.path().join("out.glb");
    ok(&[
        "convert",
        s(&cube),
        "-o",
        s(&glb),
        "--resolution",
        "32",
        "--attributes",
    ]);
    let bytes = std::fs::read(&glb).unwrap_or_else(|e| panic!("{e}"));
    let json_len = u32::from_le_bytes([bytes[12], bytes[13], bytes[14], bytes[15]]) as usize;
    let json: serde_json::Value =
        serde_json::from_slice(&bytes[20..20 + json_len]).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        json["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"],
        2
    );
    let view = &json["bufferViews"][2];
    let offset = 20 + json_len + 8 + view["byteOffset"].as_u64().unwrap_or(0) as usize;
    // glTF's COLOR_0 is linear: sRGB 200 is linear 0.578 (147 of 255).
    let first_colour = &bytes[offset..offset + 4];
    assert!(
        (i32::from(first_colour[0]) - 147).abs() <= 1,
        "{first_colour:?}"
    );

    let stl = dir.path().join("out.stl");
    let out = sparc3d(&[
        "convert",
        s(&cube),
        "-o",
        s(&stl),
        "--resolution",
        "32",
        "--attributes",
    ]);
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("holds no vertex colours"), "{err}");
}

#[test]
fn show_writes_an_item_of_a_job_with_attributes_in_the_colours_convert_writes() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let meshes = dir.path().join("meshes");
    std::fs::create_dir(&meshes).unwrap_or_else(|e| panic!("{e}"));
    std::fs::copy(
        common::example("box_textured.glb"),
        meshes.join("box_textured.glb"),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let config = dir.path().join("config.toml");
    std::fs::write(&config, "[attributes]\nenabled = true\n").unwrap_or_else(|e| panic!("{e}"));
    let job = dir.path().join("job");
    let res = "48";
    ok(&[
        "run",
        s(&meshes),
        "--job",
        s(&job),
        "--config",
        s(&config),
        "--resolution",
        res,
        "--workers",
        "1",
    ]);
    let shown = dir.path().join("shown.ply");
    ok(&["show", s(&job), "--id", "box_textured.glb", "-o", s(&shown)]);
    let converted = dir.path().join("converted.ply");
    let source = meshes.join("box_textured.glb");
    ok(&[
        "convert",
        s(&source),
        "-o",
        s(&converted),
        "--resolution",
        res,
        "--attributes",
    ]);
    let colours = ply_colours(&shown);
    assert_eq!(colours, ply_colours(&converted));
    let distinct: std::collections::BTreeSet<[u8; 4]> = colours.iter().copied().collect();
    assert!(
        distinct.len() > 1,
        "a textured box in one colour: {distinct:?}"
    );
}

/// The six face colours of [`six_colour_cube`] (sRGB), in the order −x, +x, −y, +y, −z, +z.
const SIX: [[u8; 3]; 6] = [
    [230, 25, 75],
    [60, 180, 75],
    [255, 225, 25],
    [0, 130, 200],
    [245, 130, 48],
    [145, 30, 180],
];

/// The unit cube as an OBJ whose faces take six materials (`Kd` only), face `f` of
/// [`SIX`] the colour `SIX[f]`; and the same cube without its material library.
fn six_colour_cube(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let mut mtl = String::new();
    for (f, c) in SIX.iter().enumerate() {
        // Kd is read as sRGB (as the viewers that write MTL show it): the bytes over 255.
        let k = c.map(|b| f32::from(b) / 255.0);
        mtl += &format!("newmtl face{f}\nKd {} {} {}\n", k[0], k[1], k[2]);
    }
    std::fs::write(dir.join("six.mtl"), mtl).unwrap_or_else(|e| panic!("{e}"));
    let (corners, faces) = common::boxed([1.0; 3], [0.0; 3]);
    let mut geometry = String::new();
    for [x, y, z] in &corners {
        geometry += &format!("v {x} {y} {z}\n");
    }
    let mut coloured = String::from("mtllib six.mtl\n");
    let mut plain = String::new();
    for tri in &faces {
        // The face a triangle lies on: the axis its three corners share, and which side.
        let axis = (0..3)
            .find(|&a| tri.iter().all(|&i| corners[i][a] == corners[tri[0]][a]))
            .unwrap_or(0);
        let face = 2 * axis + usize::from(corners[tri[0]][axis] > 0.5);
        let line = format!("f {} {} {}\n", tri[0] + 1, tri[1] + 1, tri[2] + 1);
        coloured += &format!("usemtl face{face}\n{line}");
        plain += &line;
    }
    let (with, without) = (dir.join("six.obj"), dir.join("plain.obj"));
    std::fs::write(&with, geometry.clone() + &coloured).unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(&without, geometry + &plain).unwrap_or_else(|e| panic!("{e}"));
    (with, without)
}

/// A PNG `preview` wrote, as (width, height, RGB bytes).
fn read_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{e}"));
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .unwrap_or_else(|e| panic!("{e}"));
    let mut buf = vec![0; reader.output_buffer_size().unwrap_or(0)];
    let info = reader
        .next_frame(&mut buf)
        .unwrap_or_else(|e| panic!("{e}"));
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

/// How many pixels of rows `y0..y1` of a picture `width` wide are `colour` lit by the preview's
/// headlight: each channel the colour's times one light factor (within rounding).
fn lit_pixels(png: &(u32, u32, Vec<u8>), y0: u32, y1: u32, colour: [u8; 3]) -> usize {
    let (w, _, rgb) = png;
    let row = *w as usize * 3;
    rgb[y0 as usize * row..y1 as usize * row]
        .chunks(3)
        .filter(|p| {
            let light = f32::from(p[0].max(p[1]).max(p[2]))
                / f32::from(colour[0].max(colour[1]).max(colour[2]));
            light > 0.2
                && (0..3).all(|k| (f32::from(colour[k]) * light - f32::from(p[k])).abs() <= 3.0)
        })
        .count()
}

#[test]
fn preview_draws_a_coloured_source_and_its_output_in_their_colours() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let (six, plain) = six_colour_cube(dir.path());
    let picture = |mesh: &Path, name: &str, extra: &[&str]| {
        let png = dir.path().join(name);
        let mut args = vec!["preview", s(mesh), "-o", s(&png), "--views", "1"];
        args.extend(["--tile", "128", "--resolution", "32"]);
        args.extend(extra);
        ok(&args);
        read_png(&png)
    };
    let coloured = picture(&six, "six.png", &[]);
    // The first camera looks from azimuth 30°, elevation 30° (towards −x, −y, −z): it sees
    // the +x, +y and +z faces. Each shows in both rows, source (rows 0–127) and output
    // (130–257), lit; the hidden faces' colours appear nowhere.
    for (face, colour) in SIX.iter().enumerate() {
        for (what, y0) in [("source", 0), ("output", 130)] {
            let n = lit_pixels(&coloured, y0, y0 + 128, *colour);
            if face % 2 == 1 {
                assert!(
                    n > 300,
                    "face {face} of the {what}: {n} pixels of {colour:?}"
                );
            } else {
                assert!(
                    n < 20,
                    "hidden face {face} in the {what}: {n} pixels of {colour:?}"
                );
            }
        }
    }
    // Without colours, the same cube is drawn as a cube without materials is: the plain
    // grey-blue picture, none of the six colours in it.
    let off = picture(&six, "off.png", &["--no-colours"]);
    let bare = picture(&plain, "plain.png", &[]);
    assert!(
        off == bare,
        "--no-colours differs from a cube without materials"
    );
    for colour in SIX {
        assert!(
            lit_pixels(&bare, 0, 258, colour) < 20,
            "{colour:?} in a plain picture"
        );
    }
}
