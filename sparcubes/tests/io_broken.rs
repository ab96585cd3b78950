//! Broken, hostile and odd inputs give a typed error that names the file, never a panic.

use sparcubes::io::{load, LoadedMesh};
use sparcubes::{Error, ErrorClass};
use std::path::{Path, PathBuf};

fn example(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../examples")
        .join(name)
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).expect("write fixture");
    p
}

/// Loads `path` expecting an error of `class` whose message names the file.
fn expect_err(path: &Path, class: ErrorClass) -> Error {
    let e = match load(path) {
        Ok(LoadedMesh { mesh, .. }) => panic!(
            "{}: loaded {} faces, expected {class:?}",
            path.display(),
            mesh.face_count()
        ),
        Err(e) => e,
    };
    assert_eq!(e.class(), class, "{}: {e}", path.display());
    let name = path.file_name().expect("name").to_string_lossy();
    assert!(
        e.to_string().contains(&*name),
        "message does not name the file: {e}"
    );
    e
}

/// Deterministic garbage: not UTF-8, no format's magic.
fn garbage(n: usize) -> Vec<u8> {
    let mut x: u32 = 0x9E37_79B9;
    (0..n)
        .map(|_| {
            x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            ((x >> 24) as u8) | 0x80
        })
        .collect()
}

const EXTS: [&str; 6] = ["obj", "ply", "stl", "off", "gltf", "glb"];

#[test]
fn empty_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    for ext in EXTS {
        expect_err(
            &write(dir.path(), &format!("empty.{ext}"), b""),
            ErrorClass::ParseError,
        );
    }
}

#[test]
fn garbage_with_every_extension() {
    let dir = tempfile::tempdir().expect("tempdir");
    for n in [1, 83, 84, 134, 4096] {
        for ext in EXTS {
            let p = write(dir.path(), &format!("garbage{n}.{ext}"), &garbage(n));
            expect_err(&p, ErrorClass::ParseError);
        }
    }
    // Text that is no mesh at all.
    for ext in EXTS {
        let p = write(
            dir.path(),
            &format!("text.{ext}"),
            b"hello world\nthis is no mesh\n",
        );
        expect_err(&p, ErrorClass::ParseError);
    }
}

#[test]
fn unknown_extension_is_sniffed_or_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    expect_err(
        &write(dir.path(), "x.dat", &garbage(500)),
        ErrorClass::UnsupportedFormat,
    );
    expect_err(
        &write(dir.path(), "noext", &garbage(500)),
        ErrorClass::UnsupportedFormat,
    );
    let ply = std::fs::read(example("cube_binary.ply")).expect("read");
    let p = write(dir.path(), "cube.bin", &ply);
    assert_eq!(load(&p).expect("sniffed PLY").mesh.face_count(), 12);
    let off = std::fs::read(example("cube.off")).expect("read");
    let p = write(dir.path(), "cube", &off);
    assert_eq!(load(&p).expect("sniffed OFF").mesh.face_count(), 12);
}

#[test]
fn extension_is_case_insensitive() {
    let dir = tempfile::tempdir().expect("tempdir");
    let stl = std::fs::read(example("wuson.stl")).expect("read");
    let p = write(dir.path(), "WUSON.StL", &stl);
    assert_eq!(load(&p).expect("load").mesh.face_count(), 3732);
}

#[test]
fn missing_file_and_folder() {
    let dir = tempfile::tempdir().expect("tempdir");
    expect_err(&dir.path().join("nothing.obj"), ErrorClass::IoError);
    let sub = dir.path().join("folder.obj");
    std::fs::create_dir(&sub).expect("mkdir");
    expect_err(&sub, ErrorClass::ParseError);
}

#[test]
fn truncated_binary_ply_and_stl() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ply = std::fs::read(example("cube_binary.ply")).expect("read");
    for cut in [1, 10, 100] {
        let p = write(
            dir.path(),
            &format!("cut{cut}.ply"),
            &ply[..ply.len() - cut],
        );
        expect_err(&p, ErrorClass::ParseError);
    }
    // Cut inside the header.
    expect_err(
        &write(dir.path(), "header.ply", &ply[..40]),
        ErrorClass::ParseError,
    );

    let stl = std::fs::read(example("wuson.stl")).expect("read");
    for cut in [1, 50, 1000, stl.len() - 90, stl.len() - 10] {
        let p = write(
            dir.path(),
            &format!("cut{cut}.stl"),
            &stl[..stl.len() - cut],
        );
        let e = expect_err(&p, ErrorClass::ParseError);
        if cut < stl.len() - 84 {
            assert!(e.to_string().contains("truncated"), "{e}");
        }
    }
}

#[test]
fn huge_claimed_counts_do_not_allocate() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n\
        property float x\nproperty float y\nproperty float z\nelement face 4000000000\n\
        property list uchar uint vertex_indices\nend_header\n\0\0\0\0";
    expect_err(&write(dir.path(), "huge.ply", ply), ErrorClass::ParseError);
    let ascii = b"ply\nformat ascii 1.0\nelement vertex 999999999999\nproperty float x\n\
        property float y\nproperty float z\nelement face 1\n\
        property list uchar int vertex_indices\nend_header\n0 0 0\n";
    expect_err(
        &write(dir.path(), "huge_ascii.ply", ascii),
        ErrorClass::ParseError,
    );
    let off = b"OFF\n999999999999 999999999999 0\n0 0 0\n";
    expect_err(&write(dir.path(), "huge.off", off), ErrorClass::ParseError);
    let mut stl = vec![0u8; 84 + 50];
    stl[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
    expect_err(&write(dir.path(), "huge.stl", &stl), ErrorClass::ParseError);
    // A face claiming 4 billion corners.
    let ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n\
        property float x\nproperty float y\nproperty float z\nelement face 1\n\
        property list uint uint vertex_indices\nend_header\n";
    let mut bytes = ply.to_vec();
    bytes.extend(std::iter::repeat_n(0u8, 36));
    bytes.extend(u32::MAX.to_le_bytes());
    bytes.extend([0u8; 12]);
    expect_err(
        &write(dir.path(), "longface.ply", &bytes),
        ErrorClass::ParseError,
    );
}

#[test]
fn nan_coordinates_in_obj() {
    let dir = tempfile::tempdir().expect("tempdir");
    let all_nan = b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let e = expect_err(
        &write(dir.path(), "nan.obj", all_nan),
        ErrorClass::EmptyMesh,
    );
    assert!(e.to_string().contains("non-finite"), "{e}");

    let some_nan = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv inf 0 0\nf 1 2 3\nf 1 2 4\nf 4 3 2\n";
    let loaded = load(&write(dir.path(), "some_nan.obj", some_nan)).expect("load");
    assert_eq!(loaded.mesh.face_count(), 1);
    assert_eq!(loaded.stats.faces_non_finite, 2);
    assert!(loaded
        .mesh
        .positions
        .iter()
        .flatten()
        .all(|c| c.is_finite()));
}

/// Loads `bytes` as `name` and returns it, expecting `faces` kept and `dropped` faces dropped
/// for a bad index, the first one's place naming `place`.
fn expect_dropped(dir: &Path, name: &str, bytes: &[u8], faces: usize, dropped: u64, place: &str) {
    let loaded = load(&write(dir, name, bytes)).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!(loaded.mesh.face_count(), faces, "{name}");
    assert_eq!(loaded.stats.faces_bad_index, dropped, "{name}");
    let first = loaded.stats.first_bad_face.unwrap_or_default();
    assert!(first.contains(place), "{name}: first bad face at {first:?}");
}

/// One rule in every format (issue 10, item 10): a face with a bad vertex index (out of
/// range, negative, not a number) is dropped and counted, the file fails only when no face
/// is left, and the message names the format and the line or element.
#[test]
fn bad_face_indices_are_dropped_and_counted_in_every_format() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let v = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n";
    for (name, face, line) in [
        ("range.obj", "f 1 2 9", "OBJ line 6"),
        ("zero.obj", "f 0 1 2", "OBJ line 6"),
        ("relative.obj", "f -1 -2 -7", "OBJ line 6"),
        ("word.obj", "f 1 x 3", "OBJ line 6"),
    ] {
        let obj = format!("{v}f 1 2 3\n{face}\nf 1 3 4\n");
        expect_dropped(d, name, obj.as_bytes(), 2, 1, line);
    }
    // Relative indices that are in range are resolved, not dropped.
    expect_dropped(
        d,
        "rel_ok.obj",
        format!("{v}f -4 -3 -2\n").as_bytes(),
        1,
        0,
        "",
    );

    let ply = |faces: &str, n: usize| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
             property float z\nelement face {n}\nproperty list uchar int vertex_indices\n\
             end_header\n0 0 0\n1 0 0\n0 1 0\n{faces}"
        )
    };
    for (name, bad) in [("neg.ply", "3 0 1 -5"), ("range.ply", "3 0 1 3")] {
        let text = ply(&format!("3 0 1 2\n{bad}\n"), 2);
        expect_dropped(d, name, text.as_bytes(), 1, 1, "PLY face element 1");
    }

    for (name, bad) in [
        ("range.off", "3 0 1 7"),
        ("neg.off", "3 0 1 -1"),
        ("word.off", "3 0 x 2"),
        ("short.off", "4 0 1 2"),
    ] {
        let off = format!("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n{bad}\n");
        expect_dropped(d, name, off.as_bytes(), 1, 1, "OFF line 7");
    }
    // A polygon with one bad corner is dropped whole, not partly kept.
    let off = b"OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n4 0 1 2 7\n";
    expect_dropped(d, "quad.off", off, 1, 1, "OFF line 7");

    // glTF: a triangle whose index is past the primitive's vertices.
    write(d, "tri.bin", &indexed_triangle_bytes([0, 1, 7]));
    let gltf = write(d, "bad.gltf", gltf_indexed("tri.bin").as_bytes());
    let e = expect_err(&gltf, ErrorClass::EmptyMesh);
    assert!(
        e.to_string().contains("glTF mesh 0 primitive 0 triangle 0"),
        "{e}"
    );

    // Nothing left: an empty-mesh error naming the format and the first bad face's place.
    for (name, bytes, place) in [
        ("all_bad.obj", format!("{v}f 1 2 9\n"), "OBJ line 5"),
        ("all_bad.ply", ply("3 0 1 -5\n", 1), "PLY face element 0"),
        (
            "all_bad.off",
            "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n".to_string(),
            "OFF line 6",
        ),
    ] {
        let e = expect_err(&write(d, name, bytes.as_bytes()), ErrorClass::EmptyMesh);
        assert!(
            e.to_string().contains(place) && e.to_string().contains("bad vertex index"),
            "{name}: {e}"
        );
    }
}

/// Runs `f` on a thread and fails the test if it does not return within a minute: a guard
/// against a hang (which is the bug), not a speed target.
fn without_hanging<T: Send + 'static>(what: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(std::time::Duration::from_secs(60))
        .unwrap_or_else(|_| panic!("{what}: still reading after a minute"))
}

/// Only regular files are meshes (issue 10, item 1): a FIFO and links to character devices
/// are refused at once, naming what they are, instead of blocking or reading forever.
#[test]
fn fifos_and_devices_are_refused_at_once() {
    without_hanging("special files", fifos_and_devices_are_refused);
}

/// Makes a FIFO at `path` and returns the path.
fn mkfifo(path: &Path) -> PathBuf {
    let made = std::process::Command::new("mkfifo")
        .arg(path)
        .status()
        .expect("mkfifo");
    assert!(made.success());
    path.to_path_buf()
}

fn fifos_and_devices_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let fifo = mkfifo(&dir.path().join("x.obj"));
    let e = expect_err(&fifo, ErrorClass::IoError);
    assert!(e.to_string().contains("FIFO"), "{e}");
    for (name, target) in [("zero.stl", "/dev/zero"), ("random.obj", "/dev/urandom")] {
        let link = dir.path().join(name);
        std::os::unix::fs::symlink(target, &link).expect("symlink");
        let e = expect_err(&link, ErrorClass::IoError);
        assert!(e.to_string().contains("character device"), "{e}");
    }
    // A glTF buffer that is a FIFO inside the folder is refused too, not waited for.
    mkfifo(&dir.path().join("pipe.bin"));
    let g = write(
        dir.path(),
        "pipe.gltf",
        gltf_with_uri("pipe.bin").as_bytes(),
    );
    let e = expect_err(&g, ErrorClass::ParseError);
    assert!(e.to_string().contains("FIFO"), "{e}");
}

#[test]
fn points_and_lines_are_counted() {
    let dir = tempfile::tempdir().expect("tempdir");
    let obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\np 1 2\nl 1 2 3\nf 1 2 3 4\n";
    let loaded = load(&write(dir.path(), "mixed.obj", obj)).expect("load");
    assert_eq!(loaded.mesh.face_count(), 2);
    assert_eq!(loaded.stats.points_skipped, 2);
    assert_eq!(loaded.stats.lines_skipped, 2);
    assert_eq!(loaded.stats.polygons_triangulated, 1);

    let only_lines = b"v 0 0 0\nv 1 0 0\nl 1 2\n";
    let e = expect_err(
        &write(dir.path(), "lines.obj", only_lines),
        ErrorClass::EmptyMesh,
    );
    assert!(e.to_string().contains("line"), "{e}");
}

#[test]
fn repeated_faces_are_dropped_and_counted() {
    // A quad listed as one polygon that goes round its corners three times (as in a parser
    // test of long face lines), then the same triangle again in the other winding: the fan
    // repeats the quad's two triangles, and fans out triangles with a repeated corner.
    let dir = tempfile::tempdir().expect("tempdir");
    let obj = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4 1 2 3 4 1 2 3 4\nf 3 2 1\n";
    let loaded = load(&write(dir.path(), "repeated.obj", obj)).expect("load");
    let kept = &loaded.mesh.triangles;
    // Fan of 12 corners: 10 triangles with 4 distinct corner sets, {1,2,3}, {1,3,4}, and the
    // degenerate {1,4,1}, {1,1,2} (kept here; the conversion skips them); the other 6 repeat
    // them, and `f 3 2 1` repeats the first.
    assert_eq!(kept[..2], [[0, 1, 2], [0, 2, 3]]);
    assert_eq!(kept.len(), 4, "{kept:?}");
    assert_eq!(loaded.stats.faces_duplicate, 7);
}

/// A minimal glTF with one triangle whose buffer comes from `uri`.
fn gltf_with_uri(uri: &str) -> String {
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
        "nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3",
            "min":[0,0,0],"max":[1,1,0]}}],
        "bufferViews":[{{"buffer":0,"byteLength":36}}],
        "buffers":[{{"byteLength":36,"uri":"{uri}"}}]}}"#
    )
}

/// A glTF with one indexed triangle (u16 indices after 36 bytes of positions) from `uri`.
fn gltf_indexed(uri: &str) -> String {
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
        "nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3",
            "min":[0,0,0],"max":[1,1,0]}},
            {{"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteLength":36}},
            {{"buffer":0,"byteOffset":36,"byteLength":6}}],
        "buffers":[{{"byteLength":42,"uri":"{uri}"}}]}}"#
    )
}

fn indexed_triangle_bytes(indices: [u16; 3]) -> Vec<u8> {
    let mut b = triangle_bytes();
    b.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    b
}

fn triangle_bytes() -> Vec<u8> {
    [0f32, 0., 0., 1., 0., 0., 0., 1., 0.]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .collect()
}

#[test]
fn gltf_buffers_only_from_own_folder_or_data_uri() {
    let root = tempfile::tempdir().expect("tempdir");
    let dir = root.path().join("models");
    std::fs::create_dir(&dir).expect("mkdir");
    // A real file outside the folder that must never be read.
    write(root.path(), "secret.bin", &triangle_bytes());
    write(&dir, "tri.bin", &triangle_bytes());

    let ok = write(&dir, "ok.gltf", gltf_with_uri("tri.bin").as_bytes());
    assert_eq!(load(&ok).expect("relative uri").mesh.face_count(), 1);
    let ok = write(&dir, "ok_dot.gltf", gltf_with_uri("./tri.bin").as_bytes());
    assert_eq!(load(&ok).expect("./ uri").mesh.face_count(), 1);

    use base64::Engine as _;
    let b64 = base64::engine::general_purpose::STANDARD.encode(triangle_bytes());
    let uri = format!("data:application/octet-stream;base64,{b64}");
    let ok = write(&dir, "data.gltf", gltf_with_uri(&uri).as_bytes());
    assert_eq!(load(&ok).expect("data uri").mesh.face_count(), 1);

    let secret = root.path().join("secret.bin");
    std::os::unix::fs::symlink(&secret, dir.join("link.bin")).expect("symlink");
    std::fs::create_dir(dir.join("sub")).expect("mkdir");
    std::os::unix::fs::symlink("../../secret.bin", dir.join("sub/link.bin")).expect("symlink");
    // A link that stays inside the folder is followed.
    std::os::unix::fs::symlink("tri.bin", dir.join("inside.bin")).expect("symlink");
    let ok = write(&dir, "inside.gltf", gltf_with_uri("inside.bin").as_bytes());
    assert_eq!(load(&ok).expect("link inside").mesh.face_count(), 1);
    for (name, uri) in [
        ("dotdot.gltf", "../secret.bin".to_string()),
        ("dotdot_enc.gltf", "%2E%2E/secret.bin".to_string()),
        ("nested.gltf", "sub/../../secret.bin".to_string()),
        ("absolute.gltf", secret.display().to_string()),
        ("http.gltf", "http://example.com/secret.bin".to_string()),
        ("https.gltf", "https://example.com/secret.bin".to_string()),
        ("file.gltf", format!("file://{}", secret.display())),
        ("missing.gltf", "nothing_here.bin".to_string()),
        // A link inside the folder that leads out of it (issue 10, item 7).
        ("link.gltf", "link.bin".to_string()),
        ("link_sub.gltf", "sub/link.bin".to_string()),
        (
            "data_bad.gltf",
            "data:application/octet-stream;base64,@@@".to_string(),
        ),
        ("data_plain.gltf", "data:text/plain,hello".to_string()),
    ] {
        let p = write(&dir, name, gltf_with_uri(&uri).as_bytes());
        let e = expect_err(&p, ErrorClass::ParseError);
        assert!(e.to_string().contains("buffer"), "{name}: {e}");
    }
}

#[test]
fn gltf_short_buffer_and_bad_views() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "short.bin", &triangle_bytes()[..20]);
    let p = write(
        dir.path(),
        "short.gltf",
        gltf_with_uri("short.bin").as_bytes(),
    );
    expect_err(&p, ErrorClass::ParseError);

    // A buffer view that claims more than its buffer.
    write(dir.path(), "tri.bin", &triangle_bytes());
    let text = gltf_with_uri("tri.bin").replace(
        r#""bufferViews":[{"buffer":0,"byteLength":36}]"#,
        r#""bufferViews":[{"buffer":0,"byteOffset":4000000000,"byteLength":36}]"#,
    );
    let p = write(dir.path(), "view.gltf", text.as_bytes());
    expect_err(&p, ErrorClass::ParseError);
}

#[test]
fn gltf_node_transforms_are_applied() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "tri.bin", &triangle_bytes());
    // Parent translates by (10, 0, 0); child scales by 2: corners at 10 + 2 * p.
    let text = gltf_with_uri("tri.bin").replace(
        r#""nodes":[{"mesh":0}]"#,
        r#""nodes":[{"translation":[10,0,0],"children":[1]},{"scale":[2,2,2],"mesh":0}]"#,
    );
    let p = write(dir.path(), "moved.gltf", text.as_bytes());
    let m = load(&p).expect("load").mesh;
    let (lo, hi) = m.bounds().expect("bounds");
    assert_eq!(lo, [10.0, 0.0, 0.0]);
    assert_eq!(hi, [12.0, 2.0, 0.0]);
}

/// A small glTF whose nodes each reference the next one twice expands to 2^k instances
/// (issue 10, item 8): it is refused by counting node instances before reading anything.
#[test]
fn gltf_node_dag_is_bounded_before_reading() {
    let dir = tempfile::tempdir().expect("tempdir");
    write(dir.path(), "tri.bin", &triangle_bytes());
    // Node i has children [i+1, i+1]; the last node holds the mesh. 2^22 = 4M instances of
    // one triangle: 12M vertices, under the element limit, but far over the instance limit.
    let depth = 22;
    let mut nodes: Vec<String> = (0..depth)
        .map(|i| format!(r#"{{"children":[{},{}]}}"#, i + 1, i + 1))
        .collect();
    nodes.push(r#"{"mesh":0}"#.to_string());
    let text = gltf_with_uri("tri.bin").replace(
        r#""nodes":[{"mesh":0}]"#,
        &format!(r#""nodes":[{}]"#, nodes.join(",")),
    );
    assert!(
        text.len() < 2000,
        "the file stays small: {} bytes",
        text.len()
    );
    let p = write(dir.path(), "dag.gltf", text.as_bytes());
    let e = expect_err(&p, ErrorClass::TooLarge);
    assert!(e.to_string().contains("node instances"), "{e}");
    // A shallow DAG (2^4 instances) is read, every instance placed.
    let shallow = gltf_with_uri("tri.bin").replace(
        r#""nodes":[{"mesh":0}]"#,
        &format!(
            r#""nodes":[{},{{"mesh":0}}]"#,
            (0..4)
                .map(|i| format!(r#"{{"children":[{},{}]}}"#, i + 1, i + 1))
                .collect::<Vec<_>>()
                .join(",")
        ),
    );
    let p = write(dir.path(), "shallow.gltf", shallow.as_bytes());
    assert_eq!(load(&p).expect("shallow dag").mesh.face_count(), 16);
}

/// Issue 32, item 8: an OBJ with vertices but no valid face says how many vertices the file
/// has (tobj keeps only those a face uses, so the message used to say "0 vertices").
#[test]
fn an_obj_without_a_valid_face_counts_the_vertices_of_the_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cases: [(&str, &[u8], &str); 3] = [
        (
            "no_face.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\n",
            "(3 vertices and no face)",
        ),
        (
            "bad_face.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n",
            "(3 vertices; dropped 1 faces with a bad vertex index, the first at OBJ line 4",
        ),
        (
            "segment.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n",
            "(3 vertices; skipped 0 points and 1 line segments)",
        ),
    ];
    for (name, bytes, says) in cases {
        let e = expect_err(&write(dir.path(), name, bytes), ErrorClass::EmptyMesh);
        assert!(e.to_string().contains(says), "{name}: {e}");
    }
}

/// Issue 32, item 8: a 2 GB sparse all-zero `.stl` (its header claims 0 triangles) is an
/// empty mesh from its first kilobyte; `read_source` hands back no 2 GB buffer. Files whose
/// header alone is not the answer read as before.
#[test]
fn an_stl_header_claiming_no_triangle_is_empty_without_reading_the_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let big = dir.path().join("zeros.stl");
    let f = std::fs::File::create(&big).expect("create");
    f.set_len(2 << 30).expect("a sparse file of 2 GiB");
    drop(f);
    let e = match sparcubes::io::read_source(&big) {
        Ok(bytes) => panic!("read {} bytes of a file with no triangle", bytes.len()),
        Err(e) => e,
    };
    assert_eq!(e.class(), ErrorClass::EmptyMesh, "{e}");
    let text = e.to_string();
    assert!(
        text.contains("empty mesh") && text.contains("claims 0 triangles"),
        "{text}"
    );
    let e = expect_err(&big, ErrorClass::EmptyMesh);
    assert!(e.to_string().contains("claims 0 triangles"), "{e}");
    // A header alone (84 bytes) is empty too; an ascii file is read as ascii; a binary file
    // with triangles still loads.
    expect_err(
        &write(dir.path(), "header.stl", &[0u8; 84]),
        ErrorClass::EmptyMesh,
    );
    let ascii = b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
    let loaded = load(&write(dir.path(), "ascii.stl", ascii)).expect("ascii STL");
    assert_eq!(loaded.mesh.face_count(), 1);
    let loaded = load(&example("wuson.stl")).expect("binary STL");
    assert!(loaded.mesh.face_count() > 0);
}

#[test]
fn gltf_buffers_through_a_reader_get_only_checked_relative_paths() {
    // A glTF fetched from a URL reads its buffers through a reader of paths relative to it:
    // the reader sees the same paths a file on disk may read, and none of the refused ones.
    let asked = std::cell::RefCell::new(Vec::new());
    let reader = |rel: &str| -> Result<Vec<u8>, String> {
        asked.borrow_mut().push(rel.to_string());
        match rel {
            "tri.bin" | "sub/tri 1.bin" => Ok(triangle_bytes()),
            _ => Err("404 not found".into()),
        }
    };
    let load = |uri: &str| {
        let text = gltf_with_uri(uri);
        let path = Path::new("https://host/models/scene.gltf");
        sparcubes::io::load_read_with(
            text.as_bytes(),
            path,
            sparcubes::io::Buffers::Relative(&reader),
        )
    };
    for uri in ["tri.bin", "./tri.bin", "sub/tri%201.bin"] {
        let loaded = load(uri).unwrap_or_else(|e| panic!("{uri}: {e}"));
        assert_eq!(loaded.mesh.face_count(), 1, "{uri}");
    }
    assert_eq!(*asked.borrow(), ["tri.bin", "tri.bin", "sub/tri 1.bin"]);
    asked.borrow_mut().clear();
    for uri in [
        "../secret.bin",
        "%2E%2E/secret.bin",
        "/etc/passwd",
        "http://x/y.bin",
    ] {
        let e = load(uri).err().unwrap_or_else(|| panic!("{uri} loaded"));
        assert!(e.to_string().contains("refusing buffer uri"), "{uri}: {e}");
    }
    assert!(asked.borrow().is_empty(), "{:?}", asked.borrow());
    let e = load("gone.bin")
        .err()
        .unwrap_or_else(|| panic!("gone.bin loaded"));
    assert!(
        e.to_string()
            .contains("cannot read buffer `gone.bin`: 404 not found"),
        "{e}"
    );
}

/// Issue 64 item 10: the PLY parser's causes come out in words, never as Rust debug text
/// (`ParseIntError { kind: PosOverflow }`, a grammar error's struct).
#[test]
fn ply_errors_say_their_cause_in_words_never_in_rust_debug_text() {
    let dir = tempfile::tempdir().expect("tempdir");
    let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                end_header\n";
    let cases = [
        (
            "overflow.ply",
            format!("{head}0 0 0\n1 0 0\n0 1 0\n3 0 1 99999999999\n"),
            "element at index 2: a number too large for its type",
        ),
        (
            "word.ply",
            format!("{head}0 0 0\n1 0 0\nzero 1 0\n3 0 1 2\n"),
            "String: 'zero 1 0'",
        ),
        (
            "grammar.ply",
            head.replace("element vertex 3", "element vertex three"),
            "PLY grammar",
        ),
    ];
    for (name, text, words) in cases {
        let e = expect_err(
            &write(dir.path(), name, text.as_bytes()),
            ErrorClass::ParseError,
        );
        let message = e.to_string();
        assert!(message.contains(words), "{name}: {message}");
        for debug in [
            "{",
            "Error {",
            "kind:",
            "ParseIntError",
            "ParseFloatError",
            "\n",
        ] {
            assert!(!message.contains(debug), "{name}: {debug:?} in {message}");
        }
    }
}
