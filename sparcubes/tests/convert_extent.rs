//! Meshes too small or too large for single-precision coordinates are refused with a clear
//! error instead of a silently wrong output (issue 10, item 9).

use sparcubes::normalize::{MAX_EXTENT, MIN_EXTENT};
use sparcubes::{convert, ErrorClass, Params};

/// An OBJ cube of side `side` at the origin, as text.
fn cube_obj(side: f64) -> String {
    let mut s = String::new();
    for i in 0..8 {
        let c = |bit: usize| if i >> bit & 1 == 1 { side } else { 0.0 };
        s.push_str(&format!("v {:e} {:e} {:e}\n", c(0), c(1), c(2)));
    }
    for f in [
        [1, 3, 2],
        [2, 3, 4],
        [5, 6, 7],
        [6, 8, 7],
        [1, 2, 5],
        [2, 6, 5],
        [3, 7, 4],
        [4, 7, 8],
        [1, 5, 3],
        [3, 5, 7],
        [2, 4, 6],
        [4, 8, 6],
    ] {
        s.push_str(&format!("f {} {} {}\n", f[0], f[1], f[2]));
    }
    s
}

fn convert_cube(side: f64) -> Result<sparcubes::Conversion, sparcubes::Error> {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("cube.obj");
    std::fs::write(&path, cube_obj(side)).expect("write");
    let loaded = sparcubes::io::load(&path).expect("the cube loads");
    convert(&loaded.mesh, &Params::with_resolution(32))
}

#[test]
fn subnormal_cube_is_refused() {
    // Side 3e-45: its f32 coordinates are the subnormals 0 and 2.8e-45.
    let e = convert_cube(3e-45).expect_err("a subnormal cube must not convert");
    assert_eq!(e.class(), ErrorClass::EmptyMesh, "{e}");
    assert!(e.to_string().contains("smallest extent"), "{e}");
    let e = convert_cube(MIN_EXTENT / 10.0).expect_err("below the minimum");
    assert_eq!(e.class(), ErrorClass::EmptyMesh, "{e}");
}

#[test]
fn huge_cube_is_refused() {
    let e = convert_cube(MAX_EXTENT * 10.0).expect_err("above the maximum");
    assert_eq!(e.class(), ErrorClass::TooLarge, "{e}");
    assert!(e.to_string().contains("largest extent"), "{e}");
}

#[test]
fn small_and_large_real_scales_convert_alike() {
    // A nanometre cube and a cube of 1e12 units give the same cells as a unit cube.
    let unit = convert_cube(1.0).expect("unit cube").cubes;
    for side in [1e-9, 1e12] {
        let c = convert_cube(side).expect("in range").cubes;
        assert_eq!(c.cells, unit.cells, "side {side}");
    }
}
