//! Hole filling: boundary loops are found, filled with triangles that agree with the
//! surface's orientation, and the result is closed and manifold.

use sparcubes::extract::{extract, sample_box};
use sparcubes::holes::{boundary_loops, fill_holes};
use sparcubes::topology::{check, weld};
use sparcubes::TriMesh;

/// The unit cube, outward, two triangles per face (face `f` = triangles `2f`, `2f + 1`).
fn cube() -> TriMesh {
    let positions = (0..8)
        .map(|i| [(i & 1) as f32, (i >> 1 & 1) as f32, (i >> 2 & 1) as f32])
        .collect();
    let quads = [
        [0, 4, 6, 2], // x = 0
        [1, 3, 7, 5], // x = 1
        [0, 1, 5, 4], // y = 0
        [2, 6, 7, 3], // y = 1
        [0, 2, 3, 1], // z = 0
        [4, 5, 7, 6], // z = 1
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    TriMesh::new(positions, triangles)
}

#[test]
fn closed_cube_is_left_alone() {
    let m = cube();
    assert!(check(&m).is_closed_oriented_manifold());
    assert!((m.signed_volume() - 1.0).abs() < 1e-12);
    let (filled, stats) = fill_holes(&m);
    assert_eq!(filled, m);
    assert_eq!(stats.holes, 0);
}

#[test]
fn cube_with_a_missing_face_is_closed_again() {
    for face in 0..6 {
        let mut m = cube();
        m.triangles.drain(2 * face..2 * face + 2);
        assert_eq!(check(&m).boundary_edges, 4);
        let (loops, open) = boundary_loops(&m);
        assert_eq!((loops.len(), open), (1, 0));
        assert_eq!(loops[0].len(), 4);
        let (filled, stats) = fill_holes(&m);
        assert_eq!(
            (stats.holes, stats.filled, stats.triangles_added),
            (1, 1, 2)
        );
        let r = check(&filled);
        assert!(r.is_closed_oriented_manifold(), "face {face}: {r:?}");
        assert!((filled.signed_volume() - 1.0).abs() < 1e-9, "face {face}");
    }
}

#[test]
fn unindexed_cube_is_filled_after_welding() {
    let mut m = cube();
    m.triangles.drain(0..2);
    let soup = TriMesh::new(
        m.triangles
            .iter()
            .flatten()
            .map(|&v| m.positions[v as usize])
            .collect(),
        (0..m.triangles.len() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect(),
    );
    let (filled, _) = fill_holes(&weld(&soup));
    assert!(check(&filled).is_closed_oriented_manifold());
    assert!((filled.signed_volume() - 1.0).abs() < 1e-9);
}

#[test]
fn sphere_with_several_holes_is_closed_again() {
    let c = [16.3, 16.1, 15.8];
    let r = 10.0;
    let cubes = sample_box(32, [0; 3], [32; 3], |p| {
        let d = (0..3)
            .map(|a| (p[a] as f64 - c[a]).powi(2))
            .sum::<f64>()
            .sqrt();
        ((d - r) as f32, [0.0; 3])
    });
    let sphere = extract(&cubes);
    let volume = sphere.signed_volume();
    // Punch four holes of different sizes.
    let holes = [
        ([c[0] + r, c[1], c[2]], 2.5),
        ([c[0] - r, c[1], c[2]], 4.0),
        ([c[0], c[1], c[2] + r], 1.2),
        ([c[0], c[1] + 0.6 * r, c[2] - 0.8 * r], 3.0),
    ];
    let mut m = sphere.clone();
    m.triangles.retain(|t| {
        let mid: [f64; 3] = std::array::from_fn(|a| {
            t.iter()
                .map(|&v| m.positions[v as usize][a] as f64)
                .sum::<f64>()
                / 3.0
        });
        holes
            .iter()
            .all(|(h, rad)| (0..3).map(|a| (mid[a] - h[a]).powi(2)).sum::<f64>().sqrt() > *rad)
    });
    assert!(m.triangles.len() < sphere.triangles.len());
    let (loops, _) = boundary_loops(&m);
    assert_eq!(loops.len(), 4);
    let (filled, stats) = fill_holes(&m);
    assert_eq!((stats.holes, stats.filled, stats.unfilled), (4, 4, 0));
    let report = check(&filled);
    assert!(report.is_closed_oriented_manifold(), "{report:?}");
    assert_eq!(report.components, 1);
    let v = filled.signed_volume();
    assert!((v - volume).abs() / volume < 0.02, "volume {v} vs {volume}");
}

/// A flat L-shaped region (five unit squares, outward normal +z): its outline is one
/// non-convex hole. Filling it must make the back face: every added triangle faces −z and
/// they cover exactly the L's area (no overlap, no fold).
#[test]
fn non_convex_hole_is_filled_without_folds() {
    let squares = [[0, 0], [1, 0], [2, 0], [0, 1], [0, 2]];
    let mut positions = Vec::new();
    let mut index = std::collections::HashMap::new();
    let mut id = |x: i32, y: i32, positions: &mut Vec<[f32; 3]>| {
        *index.entry((x, y)).or_insert_with(|| {
            positions.push([x as f32, y as f32, 0.0]);
            positions.len() as u32 - 1
        })
    };
    let mut triangles = Vec::new();
    for [x, y] in squares {
        let a = id(x, y, &mut positions);
        let b = id(x + 1, y, &mut positions);
        let c = id(x + 1, y + 1, &mut positions);
        let d = id(x, y + 1, &mut positions);
        triangles.push([a, b, c]);
        triangles.push([a, c, d]);
    }
    let m = TriMesh::new(positions, triangles);
    let (filled, stats) = fill_holes(&m);
    assert_eq!(stats.filled, 1);
    assert!(check(&filled).is_closed_oriented_manifold());
    let added = TriMesh::new(filled.positions.clone(), filled.triangles[10..].to_vec());
    let mut area = 0.0;
    for t in 0..added.triangles.len() {
        let [a, b, c] = added.triangle(t);
        let nz = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        assert!(nz <= 1e-12, "triangle {t} faces +z");
        area += -0.5 * nz;
    }
    assert!((area - 5.0).abs() < 1e-9, "filled area {area}");
}

#[test]
fn degenerate_input_does_not_panic() {
    let m = TriMesh::new(vec![[0.0; 3]; 3], vec![[0, 1, 2], [0, 0, 1], [0, 1, 7]]);
    let (_, stats) = fill_holes(&m);
    assert_eq!(stats.holes, 1);
    let (_, stats) = fill_holes(&TriMesh::default());
    assert_eq!(stats, Default::default());
}
