//! Whole conversions of generated shapes, extracted back to meshes: the output is closed,
//! 2-manifold and outward oriented; closed shapes keep their surface; open ones become thin
//! shells; no part is dropped.

use sparcubes::mesh::triangle::closest_point_on_triangle;
use sparcubes::{convert, extract, shapes, topology, Params, SparseCubes, TriMesh};

fn convert_extract(mesh: &TriMesh, n: u32, deform: bool) -> (SparseCubes, TriMesh) {
    let mut p = Params::with_resolution(n);
    p.deform = deform;
    let c = convert(mesh, &p).expect("convert").cubes;
    let out = extract(&c);
    (c, out)
}

fn assert_closed_manifold(name: &str, out: &TriMesh) {
    let r = topology::check(out);
    assert!(
        r.is_watertight() && r.is_manifold() && r.inconsistently_oriented_edges == 0,
        "{name}: {r:?}"
    );
    assert!(
        out.signed_volume() > 0.0,
        "{name}: volume {}",
        out.signed_volume()
    );
}

/// Mean and max distance (voxels) from the output's vertices to the source surface, with
/// the source mapped into grid coordinates.
fn distance_to_source(c: &SparseCubes, source: &TriMesh, out: &TriMesh) -> (f64, f64) {
    let tris: Vec<[[f64; 3]; 3]> = (0..source.triangles.len())
        .map(|t| {
            source
                .triangle(t)
                .map(|p| c.normalization.source_to_grid(p, c.resolution))
        })
        .collect();
    let mut sum = 0.0;
    let mut max: f64 = 0.0;
    for p in &out.positions {
        let p = [p[0] as f64, p[1] as f64, p[2] as f64];
        let d = tris
            .iter()
            .map(|t| {
                let q = closest_point_on_triangle(p, t);
                ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
            })
            .fold(f64::INFINITY, f64::min);
        sum += d;
        max = max.max(d);
    }
    (sum / out.positions.len() as f64, max)
}

#[test]
fn closed_shapes_stay_on_their_surface() {
    let shapes = [
        ("sphere", shapes::sphere([0.0; 3], 1.0, 24)),
        ("cube", shapes::cuboid([-1.0; 3], [1.0; 3], &[])),
        ("torus", shapes::torus([0.0; 3], 1.0, 0.35, 24)),
    ];
    for (name, mesh) in &shapes {
        for deform in [false, true] {
            let (c, out) = convert_extract(mesh, 48, deform);
            assert_closed_manifold(name, &out);
            let (mean, max) = distance_to_source(&c, mesh, &out);
            assert!(
                mean <= 0.1,
                "{name} deform={deform}: mean distance {mean} voxels"
            );
            assert!(
                max <= 0.5,
                "{name} deform={deform}: max distance {max} voxels"
            );
        }
    }
}

#[test]
fn open_shapes_become_thin_closed_shells() {
    let shapes = [
        ("quad", shapes::quad(-1.0, -1.0, 1.0, 1.0, 0.1)),
        (
            "open cylinder",
            shapes::open_cylinder([0.0, 0.0], 0.7, -1.0, 1.0, 32),
        ),
        (
            "box missing a face",
            shapes::cuboid([-1.0; 3], [1.0; 3], &[5]),
        ),
    ];
    for (name, mesh) in &shapes {
        for deform in [false, true] {
            let (c, out) = convert_extract(mesh, 48, deform);
            assert_closed_manifold(name, &out);
            // Thickness: every output point is within t (≤ 1 voxel) of the sheet, so the
            // shell is at most 2 voxels thick.
            let (mean, max) = distance_to_source(&c, mesh, &out);
            assert!(
                max <= 1.0,
                "{name} deform={deform}: max distance {max} voxels"
            );
            assert!(
                mean >= 0.5,
                "{name} deform={deform}: a shell, mean offset {mean}"
            );
        }
    }
}

#[test]
fn sub_voxel_hole_is_sealed() {
    let n = 48;
    let mesh = shapes::cube_with_hole([-1.0; 3], [1.0; 3], 0.5 * 2.0 / n as f64);
    let (c, out) = convert_extract(&mesh, n, false);
    assert_closed_manifold("cube with hole", &out);
    assert_eq!(
        topology::check(&out).components,
        1,
        "one closed surface, no inner shell"
    );
    let (mean, _) = distance_to_source(&c, &mesh, &out);
    assert!(mean <= 0.1, "mean distance {mean}");
}

#[test]
fn every_part_is_kept_even_tiny_ones() {
    let voxel = 2.0 / 64.0;
    let mesh = shapes::merge(&[
        shapes::sphere([-0.5, 0.0, 0.0], 0.4, 16),
        shapes::cuboid([0.5, -0.2, -0.2], [0.9, 0.2, 0.2], &[]),
        // Two voxels across: the smallest part that must survive.
        shapes::cuboid(
            [0.0, 0.8, 0.8],
            [2.0 * voxel, 0.8 + 2.0 * voxel, 0.8 + 2.0 * voxel],
            &[],
        ),
        shapes::quad(-1.0, -1.0, -0.6, -0.6, -0.9),
    ]);
    // Stretch the bounding box to [-1, 1]³ so the voxel is what we think.
    let mesh = shapes::merge(&[mesh, shapes::quad(0.99, 0.99, 1.0, 1.0, 1.0)]);
    let (_, out) = convert_extract(&mesh, 64, true);
    assert_closed_manifold("parts", &out);
    assert!(
        topology::check(&out).components >= 5,
        "{:?}",
        topology::check(&out)
    );
}

#[test]
fn nested_shells_and_non_manifold_input() {
    let nested = shapes::merge(&[
        shapes::sphere([0.0; 3], 1.0, 24),
        shapes::sphere([0.0; 3], 0.5, 16),
    ]);
    // With the inside test (the default) the inner solid sphere lies in solid material with
    // no air between: one solid, no interior surface (docs/ALGORITHM.md §6). Without it the
    // inner surface stays, a closed sheet of its own.
    let (_, out) = convert_extract(&nested, 48, true);
    assert_closed_manifold("nested", &out);
    assert_eq!(topology::check(&out).components, 1);
    let off = Params {
        deform: true,
        inside_test: false,
        ..Params::with_resolution(48)
    };
    let out = extract(&convert(&nested, &off).expect("convert").cubes);
    assert_closed_manifold("nested without the inside test", &out);
    assert!(topology::check(&out).components >= 2);
    // Two cubes sharing an edge: non-manifold input.
    let pair = shapes::merge(&[
        shapes::cuboid([0.0; 3], [1.0; 3], &[]),
        shapes::cuboid([1.0, 1.0, 0.0], [2.0, 2.0, 1.0], &[]),
    ]);
    let (c, out) = convert_extract(&pair, 48, true);
    assert_closed_manifold("edge-sharing cubes", &out);
    let (mean, _) = distance_to_source(&c, &pair, &out);
    assert!(mean <= 0.1, "mean distance {mean}");
}

#[test]
fn sliver_sheet_crossed_by_no_grid_edge_is_kept() {
    // A lone triangle 2.7 voxels long whose projections contain no grid line: no grid edge
    // crosses it, so nothing votes on its side; it must still become a shell (b9_mesh.off of
    // the dev corpus lost such a triangle).
    let n = 32;
    let frame = shapes::merge(&[
        shapes::quad(-1.0, -1.0, -0.95, -0.95, -1.0),
        shapes::quad(0.95, 0.95, 1.0, 1.0, 1.0),
    ]);
    let bounds = frame.bounds().expect("bounds");
    let norm = sparcubes::Normalization::fit(bounds, n, Params::default().margin_cells);
    let grid = [[10.1, 10.1, 20.5], [10.9, 10.2, 20.52], [10.2, 12.8, 20.51]];
    let corners: Vec<[f64; 3]> = grid.iter().map(|&g| norm.grid_to_source(g, n)).collect();
    let sliver = TriMesh::new(
        corners
            .iter()
            .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32])
            .collect(),
        vec![[0, 1, 2]],
    );
    let mesh = shapes::merge(&[frame, sliver]);
    let (c, out) = convert_extract(&mesh, n, false);
    assert_closed_manifold("sliver", &out);
    for &g in &grid {
        let g = c
            .normalization
            .source_to_grid(c.normalization.grid_to_source(g, n), n);
        let nearest = out
            .positions
            .iter()
            .map(|p| {
                ((p[0] as f64 - g[0]).powi(2)
                    + (p[1] as f64 - g[1]).powi(2)
                    + (p[2] as f64 - g[2]).powi(2))
                .sqrt()
            })
            .fold(f64::INFINITY, f64::min);
        assert!(
            nearest <= 1.5,
            "sliver corner {g:?} is {nearest} voxels from the output"
        );
    }
}

#[test]
fn band_grows_past_the_walls_only_for_shells() {
    // Closed parts: the zero level set stays in the wall cells, so no ring cell and a band of
    // about the stored vertices (the corners of the wall cells).
    for (name, mesh) in [
        ("sphere", shapes::sphere([0.0; 3], 1.0, 24)),
        ("torus", shapes::torus([0.0; 3], 1.0, 0.35, 24)),
    ] {
        let s = convert(&mesh, &Params::with_resolution(64))
            .expect("convert")
            .stats;
        assert_eq!(s.ring_cells, 0, "{name}: {s:?}");
        assert!(
            (s.band_vertices as f64) < 1.5 * s.active_vertices as f64,
            "{name}: {s:?}"
        );
    }
    // An open sheet: the shell at t from the sheet reaches the cells next to the walls.
    let quad = shapes::quad(-1.0, -1.0, 1.0, 1.0, 0.1);
    let c = convert(&quad, &Params::with_resolution(64)).expect("convert");
    assert!(c.stats.ring_cells > 0, "{:?}", c.stats);
    assert_closed_manifold("quad", &extract(&c.cubes));
}
