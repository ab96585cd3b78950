//! The conversion's fields on generated shapes with known geometry: signs, distances, shells,
//! determinism. (Extraction-level checks live in convert_meshes.rs.)

use sparcubes::shapes;
use sparcubes::{convert, Params, TriMesh};

fn params(n: u32, deform: bool) -> Params {
    let mut p = Params::with_resolution(n);
    p.deform = deform;
    p
}

/// Grid position of a stored vertex (deformation applied) mapped back to source units.
fn source_pos(c: &sparcubes::SparseCubes, i: usize) -> [f64; 3] {
    let g = [
        c.coords[i][0] as f64 + c.deformation[i][0] as f64,
        c.coords[i][1] as f64 + c.deformation[i][1] as f64,
        c.coords[i][2] as f64 + c.deformation[i][2] as f64,
    ];
    c.normalization.grid_to_source(g, c.resolution)
}

fn check_invariants(c: &sparcubes::SparseCubes) {
    assert!(
        c.coords.windows(2).all(|w| w[0] < w[1]),
        "coords sorted, unique"
    );
    assert!(
        c.cells.windows(2).all(|w| w[0] < w[1]),
        "cells sorted, unique"
    );
    assert_eq!(c.sdf.len(), c.coords.len());
    assert_eq!(c.deformation.len(), c.coords.len());
    for cell in &c.cells {
        let mut signs = [false; 2];
        for d in 0..8u16 {
            let v = [
                cell[0] + (d & 1),
                cell[1] + ((d >> 1) & 1),
                cell[2] + (d >> 2),
            ];
            let i = c
                .vertex_index(v)
                .expect("every corner of an active cell is active");
            signs[(c.sdf[i] < 0.0) as usize] = true;
        }
        assert!(
            signs[0] && signs[1],
            "active cell {cell:?} has a sign change"
        );
    }
}

#[test]
fn closed_sphere_sdf_is_the_true_signed_distance() {
    let mesh = shapes::sphere([0.0; 3], 1.0, 64);
    let out = convert(&mesh, &params(64, false)).expect("convert");
    let c = &out.cubes;
    check_invariants(c);
    assert_eq!(out.stats.shell_vertices, 0, "a closed surface has no shell");
    let voxel = 1.0 / (c.normalization.scale * c.resolution as f64);
    let mut worst: f64 = 0.0;
    for i in 0..c.coords.len() {
        let p = source_pos(c, i);
        let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        // The polygonal sphere is inside the true one by at most r(1 − cos(π/64)) ≈ 0.0012.
        let expected = (r - 1.0) / voxel;
        worst = worst.max((c.sdf[i] as f64 - expected).abs());
    }
    assert!(
        worst < 0.15,
        "sdf off the analytic distance by {worst} voxels"
    );
}

#[test]
fn open_quad_becomes_a_shell_on_both_sides() {
    let mesh = shapes::quad(-1.0, -1.0, 1.0, 1.0, 0.0);
    let out = convert(&mesh, &params(48, false)).expect("convert");
    let c = &out.cubes;
    check_invariants(c);
    assert!(out.stats.shell_vertices > 0);
    let voxel = 1.0 / (c.normalization.scale * c.resolution as f64);
    let sheet = c.normalization.source_to_grid([0.0; 3], c.resolution)[2];
    for i in 0..c.coords.len() {
        if c.sdf[i] < 0.0 {
            let z = source_pos(c, i)[2] / voxel;
            assert!(z.abs() < 0.9, "inside vertex {z} voxels from the sheet");
        }
    }
    // The shell's surface lies in cells on both sides of the sheet.
    let spans = |z: f64| {
        c.cells
            .iter()
            .filter(|k| (k[2] as f64) <= z && z <= k[2] as f64 + 1.0)
            .count()
    };
    let (above, below) = (spans(sheet + 0.9), spans(sheet - 0.9));
    assert!(above > 100 && below > 100, "above {above}, below {below}");
}

#[test]
fn thin_closed_plate_is_kept_as_a_shell() {
    // 0.3 voxels thick at N = 64: no grid vertex is inside it.
    let t = 0.3 / 64.0 * 2.0;
    let mesh = shapes::cuboid([-1.0, -1.0, -t / 2.0], [1.0, 1.0, t / 2.0], &[]);
    let out = convert(&mesh, &params(64, false)).expect("convert");
    assert!(
        out.stats.shell_vertices > 0,
        "thin plate treated as a shell"
    );
    assert!(
        out.cubes.cells.len() > 1000,
        "plate kept: {} cells",
        out.cubes.cells.len()
    );
}

#[test]
fn nested_shells_both_present() {
    // Without the inside test: with it (the default) a solid inside a solid with no air
    // between is one solid and the inner surface goes (docs/ALGORITHM.md §6;
    // convert_enclosed.rs checks that side).
    let outer = shapes::sphere([0.0; 3], 1.0, 48);
    let inner = shapes::sphere([0.0; 3], 0.5, 32);
    let off = Params {
        inside_test: false,
        ..params(64, false)
    };
    let out = convert(&shapes::merge(&[outer, inner]), &off).expect("convert");
    let c = &out.cubes;
    check_invariants(c);
    let voxel = 1.0 / (c.normalization.scale * c.resolution as f64);
    let near = |r0: f64| {
        c.cells
            .iter()
            .filter(|cell| {
                let g = [
                    cell[0] as f64 + 0.5,
                    cell[1] as f64 + 0.5,
                    cell[2] as f64 + 0.5,
                ];
                let p = c.normalization.grid_to_source(g, c.resolution);
                ((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - r0).abs() < 2.0 * voxel
            })
            .count()
    };
    assert!(
        near(1.0) > 1000 && near(0.5) > 300,
        "{} {}",
        near(1.0),
        near(0.5)
    );
}

#[test]
fn sub_voxel_hole_is_sealed_and_the_box_stays_exact() {
    let n = 64;
    let mesh = shapes::cube_with_hole([-1.0; 3], [1.0; 3], 0.4 * 2.0 / n as f64);
    let out = convert(&mesh, &params(n, false)).expect("convert");
    let c = &out.cubes;
    assert_eq!(out.stats.shell_vertices, 0, "the hole is sealed: no shell");
    assert!(c.sdf.iter().any(|&s| s < 0.0));
}

#[test]
fn big_hole_makes_the_box_a_shell() {
    let mesh = shapes::cuboid([-1.0; 3], [1.0; 3], &[5]);
    let out = convert(&mesh, &params(48, false)).expect("convert");
    assert!(out.stats.shell_vertices > out.stats.active_vertices / 2);
}

#[test]
fn flipped_normals_change_nothing() {
    let mesh = shapes::torus([0.0; 3], 1.0, 0.3, 24);
    let a = convert(&mesh, &params(48, true)).expect("convert");
    let b = convert(&shapes::flipped(&mesh), &params(48, true)).expect("convert");
    assert_eq!(a.cubes, b.cubes);
    assert_eq!(a.stats.shell_vertices, 0);
}

#[test]
fn same_bytes_with_one_and_two_threads() {
    let mesh = shapes::merge(&[
        shapes::torus([0.0; 3], 1.0, 0.3, 24),
        shapes::quad(-1.5, -1.5, 1.5, 1.5, 0.7),
    ]);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
            .install(|| convert(&mesh, &params(64, true)).expect("convert").cubes)
    };
    assert_eq!(run(1), run(2));
}

#[test]
fn empty_and_degenerate_meshes_are_errors() {
    assert!(convert(&TriMesh::default(), &params(32, true)).is_err());
    let flat = TriMesh::new(
        vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
        vec![[0, 1, 2]],
    );
    let err = convert(&flat, &params(32, true)).expect_err("zero area");
    assert_eq!(err.class(), sparcubes::ErrorClass::EmptyMesh);
}
