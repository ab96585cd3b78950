//! Every bundled example mesh loads with the expected face count.

use sparcubes::io::load;
use std::path::PathBuf;

fn example(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../examples")
        .join(name)
}

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

#[test]
fn examples_load_with_expected_face_counts() {
    // Face counts as in the dev corpus manifest (after triangulation).
    for (name, faces) in [
        ("wuson.stl", 3732),
        ("sphere.obj", 1792),
        ("cube_binary.ply", 12),
        ("cube.off", 12),
        ("box_textured.glb", 12),
    ] {
        let loaded = load(&example(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(loaded.mesh.face_count(), faces, "{name}");
        assert_eq!(loaded.stats.faces_bad_index, 0, "{name}");
        assert_eq!(loaded.stats.faces_non_finite, 0, "{name}");
        let (lo, hi) = loaded.mesh.bounds().expect("bounds");
        assert!((0..3).all(|a| hi[a] > lo[a]), "{name}: flat bounds");
    }
}

#[test]
fn closed_examples_have_positive_volume() {
    for name in [
        "sphere.obj",
        "cube_binary.ply",
        "cube.off",
        "box_textured.glb",
    ] {
        let m = load(&example(name)).expect(name).mesh;
        assert!(
            m.signed_volume() > 0.0,
            "{name}: volume {}",
            m.signed_volume()
        );
    }
}

#[test]
fn quads_in_off_are_triangulated_and_counted() {
    let loaded = load(&example("cube.off")).expect("cube.off");
    assert_eq!(loaded.stats.polygons_triangulated, 6);
    assert_eq!(loaded.mesh.positions.len(), 8);
}

#[test]
fn binary_stl_is_welded() {
    let m = load(&example("wuson.stl")).expect("wuson").mesh;
    assert!(m.positions.len() < 3 * m.face_count());
}

#[test]
fn gltf_strip_and_fan_become_triangles() {
    for name in ["Mesh_PrimitiveMode_04.gltf", "Mesh_PrimitiveMode_05.gltf"] {
        let loaded = load(&data(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let m = &loaded.mesh;
        assert_eq!(m.face_count(), 2, "{name}");
        assert!((m.area() - 1.0).abs() < 1e-6, "{name}: area {}", m.area());
        // Both triangles face the same way (+z, as the quad does).
        for t in 0..2 {
            let [a, b, c] = m.triangle(t);
            let nz = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            assert!(nz > 0.0, "{name}: triangle {t} faces -z");
        }
    }
}
