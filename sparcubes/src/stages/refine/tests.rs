//! The refinement's gradient against finite differences on small generated shapes (a cube, a
//! wedge, a sphere), and what a refinement may and may not change.

use super::*;
use crate::mesh::TriMesh;
use crate::stages::extract::{extract, sample_box};

/// A generated mesh in grid coordinates as the conversion holds its source.
fn grid_mesh(mesh: &TriMesh) -> GridMesh {
    GridMesh {
        verts: mesh.positions.iter().map(|p| p.map(f64::from)).collect(),
        tris: mesh.triangles.clone(),
    }
}

/// A triangular prism: the triangle (lo, lo), (hi, lo), (lo, hi) in xy, from z = lo to hi.
fn wedge_mesh(lo: f64, hi: f64) -> GridMesh {
    let t = [[lo, lo], [hi, lo], [lo, hi]];
    let mut verts = Vec::new();
    for z in [lo, hi] {
        for c in t {
            verts.push([c[0], c[1], z]);
        }
    }
    let tris = vec![
        [0, 2, 1],
        [3, 4, 5],
        [0, 1, 4],
        [0, 4, 3],
        [1, 2, 5],
        [1, 5, 4],
        [2, 0, 3],
        [2, 3, 5],
    ];
    GridMesh { verts, tris }
}

/// Signed distance to the box of half side `h` around `c` (exact outside, the largest axis
/// inside).
fn box_sdf(p: [f64; 3], c: f64, h: f64) -> f64 {
    let q = p.map(|x| (x - c).abs() - h);
    let out = q.map(|x| x.max(0.0));
    let outside = (out[0] * out[0] + out[1] * out[1] + out[2] * out[2]).sqrt();
    outside + q[0].max(q[1]).max(q[2]).min(0.0)
}

/// A small pseudo-random displacement in ±0.2 voxel per axis from the vertex's coordinates.
fn jitter(c: [u16; 3]) -> [f32; 3] {
    let h = (c[0] as u32 * 73856093) ^ (c[1] as u32 * 19349663) ^ (c[2] as u32 * 83492791);
    std::array::from_fn(|a| ((h >> (8 * a)) & 0xff) as f32 / 255.0 * 0.4 - 0.2)
}

/// The three shapes: their cubes (φ sampled at resolution 16, δ jittered) and sources.
fn shapes() -> Vec<(&'static str, SparseCubes, GridMesh)> {
    let (c, h) = (8.0, 4.3);
    let cube = sample_box(16, [0; 3], [16; 3], |v| {
        let p = v.map(f64::from);
        (box_sdf(p, c, h) as f32, jitter(v))
    });
    let cube_src = grid_mesh(&crate::shapes::cuboid([c - h; 3], [c + h; 3], &[]));
    let (lo, hi) = (3.7, 12.3);
    let wedge = sample_box(16, [0; 3], [16; 3], |v| {
        let p = v.map(f64::from);
        let slab = box_sdf(p, 8.0, 4.3);
        let cut = (p[0] + p[1] - (lo + hi)) / 2f64.sqrt();
        (slab.max(cut) as f32, jitter(v))
    });
    let r = 5.3;
    let sphere = sample_box(16, [0; 3], [16; 3], |v| {
        let p = v.map(|x| x as f64 - 8.0);
        (
            ((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - r) as f32,
            jitter(v),
        )
    });
    let sphere_src = grid_mesh(&crate::shapes::sphere([8.0; 3], r, 48));
    vec![
        ("cube", cube, cube_src),
        ("wedge", wedge, wedge_mesh(lo, hi)),
        ("sphere", sphere, sphere_src),
    ]
}

/// Small settings for tests: 6 views of 48² pixels (about 3 pixels a voxel).
fn small() -> RefineParams {
    RefineParams {
        views: 6,
        image: Some(48),
        steps: 12,
        rate: 0.05,
    }
}

/// The loss at `delta` with each pixel's triangle fixed to `frozen`'s (the function the
/// gradient differentiates), and the gradient on δ.
fn frozen_loss(
    surface: &Surface,
    cubes: &SparseCubes,
    delta: &[[f64; 3]],
    views: &[View],
    targets: &[Targets],
    frozen: &[Vec<u32>],
) -> (f64, Vec<[f64; 3]>) {
    let positions = surface.positions(cubes, delta);
    let traced = Traced::new(&positions, &surface.triangles);
    let mut grad = vec![[0.0; 3]; positions.len()];
    let mut loss = 0.0;
    for ((view, target), h) in views.iter().zip(targets).zip(frozen) {
        loss += view_loss(&traced, &surface.triangles, view, target, h, &mut grad).0;
    }
    (loss, surface.pull_back(&grad, delta.len()))
}

#[test]
fn the_gradient_on_the_displacements_agrees_with_finite_differences() {
    for (name, cubes, source) in shapes() {
        let surface = Surface::new(&cubes);
        let s = small();
        let views = views::views(bounds(&source), s.views, s.image_for(cubes.resolution));
        let src = Traced::new(&source.verts, &source.tris);
        let targets: Vec<Targets> = views.iter().map(|v| targets(&src, v)).collect();
        let delta: Vec<[f64; 3]> = cubes.deformation.iter().map(|d| d.map(f64::from)).collect();
        let traced = Traced::new(&surface.positions(&cubes, &delta), &surface.triangles);
        let frozen: Vec<Vec<u32>> = views
            .iter()
            .zip(&targets)
            .map(|(v, t)| hits(&traced, v, t))
            .collect();
        let (_, grad) = frozen_loss(&surface, &cubes, &delta, &views, &targets, &frozen);
        let seen = grad.iter().filter(|g| **g != [0.0; 3]).count();
        assert!(seen > 20, "{name}: only {seen} vertices pulled on");
        // Three directions: each vertex's jitter pattern turned, so every axis takes part.
        for k in 0..3usize {
            let dir: Vec<[f64; 3]> = cubes
                .coords
                .iter()
                .map(|&c| {
                    let j = jitter([c[1], c[2], c[0] + k as u16]);
                    j.map(f64::from)
                })
                .collect();
            let at = |h: f64| -> Vec<[f64; 3]> {
                delta
                    .iter()
                    .zip(&dir)
                    .map(|(d, u)| std::array::from_fn(|a| d[a] + h * u[a]))
                    .collect()
            };
            let h = 1e-5;
            let plus = frozen_loss(&surface, &cubes, &at(h), &views, &targets, &frozen).0;
            let minus = frozen_loss(&surface, &cubes, &at(-h), &views, &targets, &frozen).0;
            let fd = (plus - minus) / (2.0 * h);
            let analytic: f64 = grad
                .iter()
                .zip(&dir)
                .map(|(g, u)| g[0] * u[0] + g[1] * u[1] + g[2] * u[2])
                .sum();
            assert!(
                (fd - analytic).abs() <= 1e-5 * (1.0 + analytic.abs()),
                "{name} direction {k}: finite differences {fd}, gradient {analytic}"
            );
            assert!(analytic.abs() > 1e-3, "{name}: a direction with no slope");
        }
    }
}

#[test]
fn a_refinement_lowers_the_loss_keeps_the_bounds_and_the_mesh_closed() {
    for (name, mut cubes, source) in shapes() {
        let before = cubes.clone();
        let free = vec![true; cubes.coords.len()];
        let stats = refine(&mut cubes, &source, &free, &small(), 0.45);
        assert!(stats.loss_best < stats.loss_first, "{name}: {stats:?}");
        assert!(stats.moved_vertices > 0, "{name}");
        assert!(cubes.deformation.iter().flatten().all(|d| d.abs() <= 0.45));
        // φ and the cells are untouched: the same signs, so the same closed mesh.
        assert_eq!((&cubes.sdf, &cubes.cells), (&before.sdf, &before.cells));
        let report = crate::mesh::topology::check(&extract(&cubes));
        assert!(report.is_watertight() && report.is_manifold(), "{name}");
    }
}

#[test]
fn the_same_displacements_whatever_the_thread_count() {
    let (_, cubes, source) = shapes().swap_remove(2);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
        let pool = pool.unwrap_or_else(|e| panic!("{e}"));
        let mut c = cubes.clone();
        let free = vec![true; c.coords.len()];
        pool.install(|| refine(&mut c, &source, &free, &small(), 0.45));
        c.deformation
    };
    let one = run(1);
    assert_eq!(
        one.iter()
            .flatten()
            .map(|d| d.to_bits())
            .collect::<Vec<_>>(),
        run(2)
            .iter()
            .flatten()
            .map(|d| d.to_bits())
            .collect::<Vec<_>>()
    );
}

#[test]
fn hidden_and_frozen_vertices_keep_their_displacement() {
    // A hollow ball: its inner surface is seen by no camera.
    let (inner, outer) = (4.7, 7.3);
    let mut cubes = sample_box(16, [0; 3], [16; 3], |v| {
        let p = v.map(|x| x as f64 - 8.0);
        let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        ((inner - r).max(r - outer) as f32, jitter(v))
    });
    let src = crate::shapes::merge(&[
        crate::shapes::sphere([8.0; 3], outer, 48),
        crate::shapes::sphere([8.0; 3], inner, 48),
    ]);
    let before = cubes.clone();
    let radius = |c: [u16; 3]| {
        let p = c.map(|x| x as f64 - 8.0);
        (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt()
    };
    // Vertices with x < 8 are frozen.
    let free: Vec<bool> = cubes.coords.iter().map(|c| c[0] >= 8).collect();
    let stats = refine(&mut cubes, &grid_mesh(&src), &free, &small(), 0.45);
    assert!(stats.moved_vertices > 0);
    for (i, &c) in cubes.coords.iter().enumerate() {
        if radius(c) < 6.0 || !free[i] {
            assert_eq!(cubes.deformation[i], before.deformation[i], "{c:?}");
        }
    }
}

#[test]
fn an_output_no_camera_compares_is_refined_nowhere() {
    // The source is a ball far from the output's: every view frames the source only.
    let (_, mut cubes, _) = shapes().swap_remove(2);
    let before = cubes.deformation.clone();
    let far = grid_mesh(&crate::shapes::sphere([60.0; 3], 3.0, 24));
    let free = vec![true; cubes.coords.len()];
    let stats = refine(&mut cubes, &far, &free, &small(), 0.45);
    assert_eq!(stats.outcome, Outcome::NothingVisible);
    assert_eq!((stats.moved_vertices, stats.steps), (0, 0));
    assert_eq!(cubes.deformation, before);
    // An output whose every vertex is held (an open sheet's shell) is not even rendered.
    let held = vec![false; cubes.coords.len()];
    let src = grid_mesh(&crate::shapes::sphere([8.0; 3], 5.3, 48));
    let stats = refine(&mut cubes, &src, &held, &small(), 0.45);
    assert_eq!(
        (stats.outcome, stats.compared_pixels),
        (Outcome::NothingFree, 0)
    );
    assert_eq!(cubes.deformation, before);
}

#[test]
fn settings_out_of_range_are_refused_by_name() {
    let bad = [
        (
            RefineParams {
                views: 0,
                ..Default::default()
            },
            "refine.views",
        ),
        (
            RefineParams {
                image: Some(settings::MAX_IMAGE + 1),
                ..Default::default()
            },
            "refine.image",
        ),
        (
            RefineParams {
                steps: settings::MAX_STEPS + 1,
                ..Default::default()
            },
            "refine.steps",
        ),
        (
            RefineParams {
                rate: 0.0,
                ..Default::default()
            },
            "refine.rate",
        ),
    ];
    for (p, key) in bad {
        let e = p.validate().map_err(|e| e.to_string());
        assert!(matches!(&e, Err(m) if m.contains(key)), "{key}: {e:?}");
    }
    assert!(RefineParams::default().validate().is_ok());
}

/// Without a picture size the refinement renders 3 pixels per cell across the grid, within
/// [384, 2048]; a size that is set wins; a job file written before the automatic size (its
/// `image` stored) reads back with it, and one without `image` stays automatic.
#[test]
fn the_picture_size_follows_the_resolution_unless_set() {
    let auto = RefineParams::default();
    assert_eq!(auto.image_for(64), 384);
    assert_eq!(auto.image_for(128), 384);
    assert_eq!(auto.image_for(256), 768);
    assert_eq!(auto.image_for(512), 1536);
    assert_eq!(auto.image_for(1024), settings::MAX_IMAGE);
    let set = RefineParams {
        image: Some(500),
        ..Default::default()
    };
    assert_eq!(set.image_for(1024), 500);
    let old: RefineParams =
        serde_json::from_str(r#"{"views":12,"image":384,"steps":12,"rate":0.015}"#)
            .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(old.image_for(512), 384);
    let written = serde_json::to_string(&auto).unwrap_or_else(|e| panic!("{e}"));
    assert!(!written.contains("image"), "{written}");
    let back: RefineParams = serde_json::from_str(&written).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(back, auto);
}
