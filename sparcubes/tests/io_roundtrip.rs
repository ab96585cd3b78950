//! save → load preserves positions and triangles in every output format.

use sparcubes::io::{load, save};
use sparcubes::{ErrorClass, TriMesh};
use std::path::PathBuf;

fn example(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../examples")
        .join(name)
}

/// The corners of every triangle, bit for bit: independent of vertex order and welding.
fn corners(m: &TriMesh) -> Vec<[[u32; 3]; 3]> {
    m.triangles
        .iter()
        .map(|t| t.map(|i| m.positions[i as usize].map(f32::to_bits)))
        .collect()
}

/// A small mesh with awkward coordinates (tiny, huge, negative, many digits).
fn awkward() -> TriMesh {
    TriMesh::new(
        vec![
            [0.1, -0.2, 0.3],
            [1.0e-7, 3.402_823e38, -1.5],
            [std::f32::consts::PI, -0.0, 12345.678],
            [-1.0e-30, 2.5, 0.333_333_34],
        ],
        vec![[0, 1, 2], [0, 2, 3], [3, 2, 1]],
    )
}

#[test]
fn every_format_round_trips() {
    let dir = tempfile::tempdir().expect("tempdir");
    let sphere = load(&example("sphere.obj")).expect("sphere").mesh;
    let wuson = load(&example("wuson.stl")).expect("wuson").mesh;
    for (label, mesh) in [("awkward", awkward()), ("sphere", sphere), ("wuson", wuson)] {
        for ext in ["ply", "obj", "stl", "glb", "PLY"] {
            let path = dir.path().join(format!("{label}.{ext}"));
            save(&mesh, &path).unwrap_or_else(|e| panic!("save {label}.{ext}: {e}"));
            let back = load(&path)
                .unwrap_or_else(|e| panic!("load {label}.{ext}: {e}"))
                .mesh;
            assert_eq!(corners(&back), corners(&mesh), "{label}.{ext}");
            if ext != "stl" {
                // STL has no shared vertices: they are welded again on loading.
                assert_eq!(back.positions.len(), mesh.positions.len(), "{label}.{ext}");
            }
        }
    }
    // Nothing but the saved files is left (no temporary files).
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .expect("read_dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.starts_with('.')), "{names:?}");
}

#[test]
fn ply_and_glb_keep_vertex_order() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mesh = awkward();
    for ext in ["ply", "glb"] {
        let path = dir.path().join(format!("m.{ext}"));
        save(&mesh, &path).expect("save");
        assert_eq!(load(&path).expect("load").mesh, mesh, "{ext}");
    }
}

#[test]
fn saving_replaces_an_existing_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("m.ply");
    std::fs::write(&path, b"old contents").expect("write");
    save(&awkward(), &path).expect("save");
    assert_eq!(load(&path).expect("load").mesh, awkward());
}

#[test]
fn unknown_output_extension_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("m.fbx");
    let e = save(&awkward(), &path).unwrap_err();
    assert_eq!(e.class(), ErrorClass::UnsupportedFormat);
    assert!(e.to_string().contains("m.fbx"), "{e}");
    assert!(!path.exists());
}

#[test]
fn failed_write_leaves_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("missing-folder").join("m.ply");
    let e = save(&awkward(), &path).unwrap_err();
    assert_eq!(e.class(), ErrorClass::IoError);
    assert!(e.to_string().contains("m.ply"), "{e}");
    assert_eq!(std::fs::read_dir(dir.path()).expect("read_dir").count(), 0);
}

#[test]
fn bad_indices_are_refused_on_save() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mesh = TriMesh::new(vec![[0.0; 3]], vec![[0, 0, 4]]);
    let e = save(&mesh, &dir.path().join("m.obj")).unwrap_err();
    assert_eq!(e.class(), ErrorClass::InvalidParams);
}
