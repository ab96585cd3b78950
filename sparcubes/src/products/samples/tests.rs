//! Samples against independent references: a brute-force generalised winding number of the
//! extracted mesh (solid angles, Van Oosterom & Strackee 1983) for the sign, brute-force
//! point–triangle distances for the magnitude, and a brute-force edge search for the sharp
//! points.

use super::*;
use crate::mesh::triangle::closest_point_on_triangle;
use crate::params::Params;
use crate::shapes::{cube_with_hole, cuboid, merge, quad, sphere, torus};
use crate::vec3::{cross, dist2, dot, norm, sub};
use std::collections::HashMap;

/// Generalised winding number of `q` with respect to `mesh` (1 inside a closed, outward
/// oriented mesh, 0 outside).
pub(crate) fn winding_number(mesh: &TriMesh, q: [f64; 3]) -> f64 {
    let mut total = 0.0;
    for t in 0..mesh.triangles.len() {
        let [a, b, c] = mesh.triangle(t).map(|p| sub(p, q));
        let (la, lb, lc) = (norm(a), norm(b), norm(c));
        let det = dot(a, cross(b, c));
        let den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
        total += 2.0 * det.atan2(den);
    }
    total / (4.0 * std::f64::consts::PI)
}

fn convert(mesh: &TriMesh, resolution: u32, deform: bool) -> (SparseCubes, TriMesh) {
    let mut params = Params::with_resolution(resolution);
    params.deform = deform;
    let cubes = crate::convert(mesh, &params)
        .unwrap_or_else(|e| panic!("{e}"))
        .cubes;
    let out = crate::extract(&cubes);
    (cubes, out)
}

/// The example files shipped with the repository, by name: a closed organic mesh, a textured
/// box (glTF), a triangulated cube (OFF).
fn bundled_meshes() -> Vec<(&'static str, TriMesh)> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    ["wuson.stl", "box_textured.glb", "cube.off"]
        .into_iter()
        .map(|file| {
            let loaded =
                crate::io::load(&root.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
            (file, loaded.mesh)
        })
        .collect()
}

fn small_params(seed: u64) -> SampleParams {
    SampleParams {
        surface: 500,
        sharp: 500,
        near: 1500,
        sharp_near: 1500,
        volume: 1500,
        dtype: Precision::F32,
        seed,
        ..SampleParams::default()
    }
}

/// Fraction of points whose stored side agrees with the winding number of the mesh (grid
/// coordinates), and the largest error of |sdf| against brute force (normalized units).
fn check(cubes: &SparseCubes, mesh: &TriMesh, points: &[[f32; 3]], sdf: &[f32]) -> (f64, f64) {
    let n = cubes.resolution as f64;
    let mut agree = 0;
    let mut worst: f64 = 0.0;
    for (p, &s) in points.iter().zip(sdf) {
        let g = p.map(|c| (c as f64 + 1.0) * 0.5 * n);
        let inside = winding_number(mesh, g) > 0.5;
        if inside == (s < 0.0) {
            agree += 1;
        }
        let d2 = (0..mesh.triangles.len())
            .map(|t| dist2(g, closest_point_on_triangle(g, &mesh.triangle(t))))
            .fold(f64::INFINITY, f64::min);
        worst = worst.max((d2.sqrt() * 2.0 / n - s.abs() as f64).abs());
    }
    (agree as f64 / points.len() as f64, worst)
}

#[test]
fn signs_agree_with_winding_number_and_distances_are_exact() {
    let shapes = [
        ("sphere", sphere([0.0; 3], 0.5, 24)),
        ("torus", torus([0.0; 3], 0.6, 0.2, 24)),
        ("open box", cube_with_hole([-0.5; 3], [0.5; 3], 0.3)),
        ("sheet", quad(-0.5, -0.5, 0.5, 0.5, 0.0)),
        (
            "parts",
            merge(&[
                sphere([0.4, 0.0, 0.0], 0.3, 16),
                cuboid([-0.7, -0.3, -0.3], [-0.2, 0.3, 0.3], &[]),
            ]),
        ),
    ];
    for (name, shape) in shapes {
        for deform in [false, true] {
            let (cubes, mesh) = convert(&shape, 32, deform);
            let s = sample(&cubes, &mesh, &small_params(5)).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(s.volume_points.len(), 1500);
            assert_eq!(s.near_points.len(), 1500);
            let (vol_agree, vol_err) = check(&cubes, &mesh, &s.volume_points, &s.volume_sdf);
            let (near_agree, near_err) = check(&cubes, &mesh, &s.near_points, &s.near_sdf);
            assert!(
                vol_agree >= 0.999,
                "{name} deform={deform}: volume {vol_agree}"
            );
            assert!(
                near_agree >= 0.999,
                "{name} deform={deform}: near {near_agree}"
            );
            assert!(
                vol_err < 1e-6 && near_err < 1e-6,
                "{name}: {vol_err} {near_err}"
            );
            for (o, d) in s.volume_occupancy.iter().zip(&s.volume_sdf) {
                assert_eq!(*o == 1, *d < 0.0);
            }
        }
    }
}

#[test]
fn bundled_meshes_signs_agree_with_winding_number_and_distances_are_exact() {
    for (file, source) in bundled_meshes() {
        let (cubes, mesh) = convert(&source, 24, false);
        let s = sample(&cubes, &mesh, &small_params(3)).unwrap_or_else(|e| panic!("{e}"));
        let (vol_agree, vol_err) = check(&cubes, &mesh, &s.volume_points, &s.volume_sdf);
        let (near_agree, near_err) = check(&cubes, &mesh, &s.near_points, &s.near_sdf);
        assert!(vol_agree >= 0.999, "{file}: volume {vol_agree}");
        assert!(near_agree >= 0.999, "{file}: near {near_agree}");
        assert!(
            vol_err < 1e-6 && near_err < 1e-6,
            "{file}: {vol_err} {near_err}"
        );
    }
}

#[test]
fn surface_points_lie_on_the_mesh_with_its_normals() {
    let (cubes, mesh) = convert(&torus([0.0; 3], 0.6, 0.2, 24), 32, false);
    let s = sample(&cubes, &mesh, &small_params(1)).unwrap_or_else(|e| panic!("{e}"));
    let n = cubes.resolution as f64;
    for (p, nrm) in s.surface_points.iter().zip(&s.surface_normals) {
        let g = p.map(|c| (c as f64 + 1.0) * 0.5 * n);
        let (d2, t) = (0..mesh.triangles.len())
            .map(|t| (dist2(g, closest_point_on_triangle(g, &mesh.triangle(t))), t))
            .fold((f64::INFINITY, 0), |a, b| if b.0 < a.0 { b } else { a });
        assert!(d2.sqrt() < 1e-4, "{p:?} is {} voxels off", d2.sqrt());
        let f = mesh.face_normal(t);
        let cos = dot(f, nrm.map(f64::from)) / norm(f);
        assert!(cos > 0.999 || d2.sqrt() > 1e-9, "normal {nrm:?} vs {f:?}");
    }
}

#[test]
fn sharp_points_lie_on_edges_above_the_angle() {
    let (cubes, mesh) = convert(&cuboid([-0.5; 3], [0.5, 0.3, 0.2], &[]), 40, false);
    let mut params = small_params(2);
    params.sharp_angle_deg = 30.0;
    let s = sample(&cubes, &mesh, &params).unwrap_or_else(|e| panic!("{e}"));
    assert!(s.sharp_edges > 0);
    assert_eq!(s.sharp_points.len(), 500);
    // Every edge of the mesh with the angle between its faces' normals.
    let mut faces: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let (u, v) = (tri[k], tri[(k + 1) % 3]);
            faces.entry((u.min(v), u.max(v))).or_default().push(t);
        }
    }
    let n = cubes.resolution as f64;
    for p in &s.sharp_points {
        let g = p.map(|c| (c as f64 + 1.0) * 0.5 * n);
        let mut best = (f64::INFINITY, 0.0);
        for (&(u, v), ts) in &faces {
            let (a, b) = (
                mesh.positions[u as usize].map(f64::from),
                mesh.positions[v as usize].map(f64::from),
            );
            let ab = sub(b, a);
            let s = (dot(sub(g, a), ab) / dot(ab, ab)).clamp(0.0, 1.0);
            let d = norm(sub(
                g,
                [a[0] + s * ab[0], a[1] + s * ab[1], a[2] + s * ab[2]],
            ));
            if d < best.0 && ts.len() == 2 {
                let (n1, n2) = (mesh.face_normal(ts[0]), mesh.face_normal(ts[1]));
                let angle = (dot(n1, n2) / (norm(n1) * norm(n2)))
                    .clamp(-1.0, 1.0)
                    .acos();
                best = (d, angle.to_degrees());
            }
        }
        assert!(best.0 < 1e-4, "{p:?} is {} voxels from an edge", best.0);
        assert!(
            best.1 >= 30.0 - 1e-6,
            "{p:?} lies on an edge of {}°",
            best.1
        );
    }
    // A sphere at this resolution has no edge of 60° or more.
    let (cubes, mesh) = convert(&sphere([0.0; 3], 0.5, 32), 40, false);
    params.sharp_angle_deg = 60.0;
    let s = sample(&cubes, &mesh, &params).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((s.sharp_edges, s.sharp_points.len()), (0, 0));
    assert_eq!((s.sharp_near_points.len(), s.sharp_near_sdf.len()), (0, 0));
}

/// A box with sharp edges and its samples at `f32`, with sharp-near offsets of three σ far
/// below the bound (so the truncation leaves their spread as it is).
fn box_with_sharp_near(sigmas: &[f64]) -> (SparseCubes, TriMesh, SampleParams, Samples) {
    let (cubes, mesh) = convert(&cuboid([-0.5; 3], [0.5, 0.3, 0.2], &[]), 40, false);
    let params = SampleParams {
        sharp_near: 3000,
        sharp_near_sigmas: sigmas.to_vec(),
        sharp_angle_deg: 30.0,
        ..small_params(4)
    };
    let s = sample(&cubes, &mesh, &params).unwrap_or_else(|e| panic!("{e}"));
    (cubes, mesh, params, s)
}

#[test]
fn sharp_near_offsets_have_the_spread_of_their_sigma() {
    let sigmas = [0.002, 0.01, 0.04];
    let (cubes, mesh, params, s) = box_with_sharp_near(&sigmas);
    assert_eq!(s.sharp_near_points.len(), 3000);
    assert_eq!(s.sharp_near_sdf.len(), 3000);
    // Each point's place on the edges, drawn again from its own numbers: the offset is what
    // the point moved from it.
    let edges = sharp_edges(&mesh, params.sharp_angle_deg);
    let n = cubes.resolution as f64;
    for &sigma in &sigmas {
        let rows: Vec<usize> = sigma_rows(params.sharp_near, &sigmas, sigma).collect();
        assert_eq!(rows.len(), 1000);
        let mut sum2 = 0.0;
        for &i in &rows {
            let (on_edge, _) = edges.draw(&Draw::new(params.seed, SHARP_NEAR, i as u64));
            let base = on_edge.map(|c| 2.0 * c / n - 1.0);
            let p = s.sharp_near_points[i].map(f64::from);
            sum2 += (0..3).map(|a| (p[a] - base[a]).powi(2)).sum::<f64>();
        }
        let spread = (sum2 / (3.0 * rows.len() as f64)).sqrt();
        assert!(
            (spread / sigma - 1.0).abs() < 0.06,
            "σ {sigma}: offsets spread {spread}"
        );
    }
}

#[test]
fn sharp_near_signs_agree_with_winding_number_and_distances_are_exact() {
    let (cubes, mesh, params, s) = box_with_sharp_near(&[0.001, 0.005, 0.05]);
    assert!(s.sharp_edges > 0);
    let (agree, err) = check(&cubes, &mesh, &s.sharp_near_points, &s.sharp_near_sdf);
    assert!(agree >= 0.999, "sharp near: {agree}");
    assert!(err < 1e-6, "sharp near: {err}");
    // Inside and outside both (the offsets straddle the edges).
    let inside = s.sharp_near_sdf.iter().filter(|d| **d < 0.0).count();
    assert!(inside > 300 && inside < 2700, "{inside} of 3000 inside");
    // The same on one thread, and the other kinds as they are without sharp-near points.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap_or_else(|e| panic!("{e}"));
    let one = pool
        .install(|| sample(&cubes, &mesh, &params))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(one, s);
    let without = SampleParams {
        sharp_near: 0,
        ..params
    };
    let w = sample(&cubes, &mesh, &without).unwrap_or_else(|e| panic!("{e}"));
    assert!(w.sharp_near_points.is_empty() && w.sharp_near_sdf.is_empty());
    assert_eq!(
        Samples {
            sharp_near_points: Vec::new(),
            sharp_near_sdf: Vec::new(),
            ..s
        },
        w
    );
}

#[test]
fn sigma_rows_follow_the_cycle() {
    let sigmas = [0.001, 0.005, 0.05];
    let rows: Vec<usize> = sigma_rows(10, &sigmas, 0.005).collect();
    assert_eq!(rows, vec![1, 4, 7]);
    assert_eq!(sigma_rows(10, &sigmas, 0.001).count(), 4);
    assert_eq!(sigma_rows(10, &sigmas, 0.002).count(), 0);
    assert_eq!(sigma_rows(10, &[], 0.002).count(), 0);
    assert_eq!(
        sigma_rows(6, &[0.1, 0.2, 0.1], 0.1).collect::<Vec<_>>(),
        vec![0, 2, 3, 5]
    );
    // The defaults give every consumer its rows (SampleParams::default's doc).
    let d = SampleParams::default();
    assert_eq!(sigma_rows(d.near, &d.near_sigmas, 0.001).count(), 200_000);
    assert_eq!(sigma_rows(d.near, &d.near_sigmas, 0.05).count(), 200_000);
    for sigma in [0.001, 0.003, 0.005, 0.007, 0.01, 0.02, 0.04, 0.06] {
        assert_eq!(
            sigma_rows(d.sharp_near, &d.sharp_near_sigmas, sigma).count(),
            32_768
        );
    }
    assert!(d.validate().is_ok());
}

#[test]
fn same_samples_whatever_the_thread_count_and_seed_changes_them() {
    let (cubes, mesh) = convert(&torus([0.0; 3], 0.6, 0.2, 24), 32, false);
    let params = SampleParams {
        dtype: Precision::F16,
        ..small_params(9)
    };
    let a = sample(&cubes, &mesh, &params).unwrap_or_else(|e| panic!("{e}"));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap_or_else(|e| panic!("{e}"));
    let b = pool
        .install(|| sample(&cubes, &mesh, &params))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(a, b);
    let c = sample(&cubes, &mesh, &small_params(10)).unwrap_or_else(|e| panic!("{e}"));
    assert_ne!(a.volume_points, c.volume_points);
    // f16 storage: every value is exactly an f16, and tiny distances keep their sign.
    for v in a.near_sdf.iter().chain(a.near_points.iter().flatten()) {
        assert_eq!(half::f16::from_f32(*v).to_f32(), *v);
        assert_ne!(*v, 0.0);
    }
}

#[test]
fn bad_parameters_name_their_key() {
    let (cubes, mesh) = convert(&sphere([0.0; 3], 0.5, 12), 16, false);
    let mut p = small_params(0);
    p.volume = MAX_PER_KIND + 1;
    let e = sample(&cubes, &mesh, &p).err().map(|e| e.to_string());
    assert!(e.is_some_and(|e| e.contains("samples.volume")));
    let mut p = small_params(0);
    p.near_sigmas = vec![];
    let e = sample(&cubes, &mesh, &p).err().map(|e| e.to_string());
    assert!(e.is_some_and(|e| e.contains("samples.near_sigmas")));
    let mut p = small_params(0);
    p.sharp_near_sigmas = vec![];
    let e = sample(&cubes, &mesh, &p).err().map(|e| e.to_string());
    assert!(e.is_some_and(|e| e.contains("samples.sharp_near_sigmas")));
    p.sharp_near_sigmas = vec![0.01, -1.0];
    let e = sample(&cubes, &mesh, &p).err().map(|e| e.to_string());
    assert!(e.is_some_and(|e| e.contains("samples.sharp_near_sigmas")));
    p.sharp_near = 0;
    p.sharp_near_sigmas = vec![];
    assert!(p.validate().is_ok());
    p.sharp_near = MAX_PER_KIND + 1;
    let e = p.validate().err().map(|e| e.to_string());
    assert!(e.is_some_and(|e| e.contains("samples.sharp_near")));
    let e = sample(&cubes, &TriMesh::default(), &small_params(0)).err();
    assert!(matches!(e, Some(Error::EmptyMesh { .. })));
}

#[test]
fn face_sides_agree_with_grid_sides_on_real_meshes() {
    // The side read from the closest triangle's face replaces the grid sides where it answers:
    // on the bundled meshes, with and without deformation, both must give the same side for
    // every point near the surface and in the volume.
    for (file, source) in bundled_meshes() {
        for deform in [false, true] {
            let (cubes, mesh) = convert(&source, 48, deform);
            let n = cubes.resolution as f64;
            let points: Vec<[f64; 3]> = (0..6000u64)
                .map(|i| {
                    let d = Draw::new(5, 9, i);
                    if i % 2 == 0 {
                        let v = mesh.positions[(i as usize * 7919) % mesh.positions.len()];
                        let sigma = if i % 4 == 0 { 0.3 } else { 2.0 };
                        [0, 1, 2].map(|a| v[a] as f64 + sigma * d.normal(a as u64))
                    } else {
                        [0, 1, 2].map(|a| (1.1 * d.uniform(a) - 0.05) * n)
                    }
                })
                .collect();
            let index = TriangleIndex::new(&mesh);
            let closest = index.closest_batch(&points);
            let grid = GridSides::new(&cubes).inside_batch(&points);
            let mut answered = 0;
            for ((p, c), g) in points.iter().zip(&closest).zip(&grid) {
                if let Some(face) = index.face_side(*p, c) {
                    answered += 1;
                    assert_eq!(face, *g, "{file} deform {deform}: {p:?}");
                }
            }
            // The face answers for most points (else the test would check little).
            assert!(answered > points.len() / 4, "{file}: {answered}");
            eprintln!("{file} deform {deform}: {answered} of {}", points.len());
        }
    }
}

#[test]
fn grid_sides_are_right_for_points_on_grid_planes() {
    // Points stored as f16 lie on dyadic planes of the grid, where a segment to a cell corner
    // can pass exactly through an edge shared by two output triangles (or lie in a triangle's
    // plane). The grid sides must still agree with the winding number of the output for every
    // point not on the surface itself.
    for (file, source) in bundled_meshes() {
        for deform in [false, true] {
            let (cubes, mesh) = convert(&source, 40, deform);
            let points: Vec<[f64; 3]> = (0..2000u64)
                .map(|i| {
                    let d = Draw::new(11, 3, i);
                    let v = mesh.positions[(i as usize * 7919) % mesh.positions.len()];
                    // Within about a voxel of the surface, rounded to quarter voxels (some
                    // coordinates to whole or half voxels).
                    let step = [0.25, 0.5, 1.0][(i % 3) as usize];
                    [0, 1, 2]
                        .map(|a| ((v[a] as f64 + 0.7 * d.normal(a as u64)) / step).round() * step)
                })
                .collect();
            let index = TriangleIndex::new(&mesh);
            let closest = index.closest_batch(&points);
            let grid = GridSides::new(&cubes).inside_batch(&points);
            let mut checked = 0;
            let mut wrong = Vec::new();
            for ((p, c), g) in points.iter().zip(&closest).zip(&grid) {
                if c.distance < 1e-9 {
                    continue;
                }
                checked += 1;
                if (winding_number(&mesh, *p) > 0.5) != *g {
                    wrong.push(*p);
                }
            }
            assert!(checked > points.len() / 2, "{file}: {checked}");
            assert!(
                wrong.is_empty(),
                "{file} deform {deform}: {} of {checked} wrong, e.g. {:?}",
                wrong.len(),
                &wrong[..wrong.len().min(3)]
            );
        }
    }
}
