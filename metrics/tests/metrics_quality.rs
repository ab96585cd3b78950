//! Quality metrics (docs/QUALITY.md, "How we measure") on meshes whose answers are known in
//! closed form.

use sparc3d_metrics::{evaluate, EvalOptions, QualityReport};
use sparcubes::TriMesh;

/// An axis-aligned cube of side `side` centred at `c`, every face with its own four corners
/// (so only welding makes it closed). With `fan`, each face is four triangles around its
/// centre instead of two, so that it samples independently of the two-triangle version.
fn cube(c: [f32; 3], side: f32, fan: bool) -> TriMesh {
    let h = side / 2.0;
    let mut mesh = TriMesh::default();
    for axis in 0..3 {
        for sign in [1.0f32, -1.0] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let corner = |du: f32, dv: f32| {
                let mut p = c;
                p[axis] += sign * h;
                p[u] += du * h;
                p[v] += dv * h;
                p
            };
            let mut quad = vec![
                corner(-1., -1.),
                corner(1., -1.),
                corner(1., 1.),
                corner(-1., 1.),
            ];
            if sign < 0.0 {
                quad.reverse();
            }
            push_quad(&mut mesh, &quad, fan);
        }
    }
    mesh
}

/// Appends a counter-clockwise quad as two triangles, or as four around its centre.
fn push_quad(mesh: &mut TriMesh, quad: &[[f32; 3]], fan: bool) {
    let base = mesh.positions.len() as u32;
    mesh.positions.extend_from_slice(quad);
    if fan {
        let centre = [0, 1, 2].map(|a| quad.iter().map(|p| p[a]).sum::<f32>() / 4.0);
        mesh.positions.push(centre);
        for k in 0..4u32 {
            mesh.triangles
                .push([base + k, base + (k + 1) % 4, base + 4]);
        }
    } else {
        mesh.triangles.push([base, base + 1, base + 2]);
        mesh.triangles.push([base, base + 2, base + 3]);
    }
}

/// `mesh` with every vertex mapped by `f`.
fn map(mesh: &TriMesh, f: impl Fn([f32; 3]) -> [f32; 3]) -> TriMesh {
    TriMesh::new(
        mesh.positions.iter().map(|&p| f(p)).collect(),
        mesh.triangles.clone(),
    )
}

/// Merges two meshes into one.
fn merge(a: &TriMesh, b: &TriMesh) -> TriMesh {
    let mut m = a.clone();
    let base = a.positions.len() as u32;
    m.positions.extend_from_slice(&b.positions);
    m.triangles
        .extend(b.triangles.iter().map(|t| t.map(|i| i + base)));
    m
}

fn options(samples: usize, resolution: u32) -> EvalOptions {
    EvalOptions {
        samples,
        seed: 7,
        resolution,
    }
}

fn eval(source: &TriMesh, output: &TriMesh, o: EvalOptions) -> QualityReport {
    match evaluate(source, output, &o) {
        Ok(r) => r,
        Err(e) => panic!("evaluate failed: {e}"),
    }
}

/// Expected point-to-point directed distance from a point at distance `delta` of a plane
/// holding a uniform (Poisson) sample of density `rho`: the nearest sample within in-plane
/// radius r exists with probability 1 − exp(−ρπr²), so
/// E = δ + ∫_δ^∞ exp(−ρπ(s² − δ²)) ds (numerically, trapezoids).
fn expected_directed(delta: f64, rho: f64) -> f64 {
    let (mut s, mut sum, ds) = (delta, 0.0, 1e-6);
    loop {
        let f = |s: f64| (-rho * std::f64::consts::PI * (s * s - delta * delta)).exp();
        let step = 0.5 * (f(s) + f(s + ds)) * ds;
        sum += step;
        s += ds;
        if step < 1e-15 {
            break;
        }
    }
    delta + sum
}

#[test]
fn identical_meshes_score_perfectly() {
    let mesh = cube([0.3, -1.0, 2.0], 2.0, false);
    let r = eval(&mesh, &mesh, options(20_000, 128));
    // Same seed, same triangles: the two samplings coincide point for point.
    assert!(r.cd < 1e-12, "cd {}", r.cd);
    assert!(r.cd_surface < 1e-12, "cd_surface {}", r.cd_surface);
    assert!(r.anc > 100.0 - 1e-9, "anc {}", r.anc);
    for f in &r.f1 {
        assert_eq!(f.f1, 100.0, "F1 at {}", f.threshold);
    }
    assert!(r.source_closed, "a welded cube is closed");
    assert!(r.output_closed);
    assert_eq!((r.components_kept, r.components_total), (1, 1));
    let offset = r.offset_voxels.unwrap_or(f64::NAN);
    assert!(offset.abs() < 1e-9, "offset {offset}");
}

#[test]
fn same_surface_other_triangulation_sits_at_the_sampling_floor() {
    let (a, b) = (cube([0.0; 3], 1.0, false), cube([0.0; 3], 1.0, true));
    let n = 20_000;
    let r = eval(&a, &b, options(n, 128));
    // Independent samplings of one surface of area 6 with n points each.
    let expected = expected_directed(0.0, n as f64 / 6.0);
    assert!((expected - r.cd_floor).abs() < 1e-3 * expected);
    assert!(
        (r.cd - expected).abs() < 0.06 * expected,
        "cd {} vs sampling floor {expected}",
        r.cd
    );
    assert!(r.cd_surface < 1e-9, "cd_surface {}", r.cd_surface);
    // Points within a sample spacing of a cube edge may pair across it (|n·n′| = 0): about
    // 12 edges × 0.009 / area 6 ≈ 1.5% of them.
    assert!(r.anc > 98.0 && r.anc < 100.0, "anc {}", r.anc);
}

#[test]
fn cube_scaled_by_one_percent_is_half_a_percent_away() {
    let source = cube([0.0; 3], 1.0, false);
    let bigger = map(&cube([0.0; 3], 1.0, true), |p| p.map(|x| x * 1.01));
    let n = 50_000;
    let resolution = 200;
    let r = eval(&source, &bigger, options(n, resolution));
    // Source points lie 0.005 inside the bigger cube's faces. Output points lie 0.005 outside
    // the source, a little more in the strips of width 0.005 beyond its edges (about 2% of
    // the area, at ≈1.15 × 0.005 on average).
    let delta = 0.005;
    let strip = 4.0 * 0.005 * 1.01 / (1.01f64 * 1.01);
    let out_to_src = delta * (1.0 + strip * 0.148);
    let analytic_surface = 0.5 * (delta + out_to_src);
    assert!(
        (r.cd_surface - analytic_surface).abs() < 0.002 * analytic_surface,
        "cd_surface {} vs {analytic_surface}",
        r.cd_surface
    );
    let analytic = 0.5
        * (expected_directed(delta, n as f64 / (6.0 * 1.0201))
            + expected_directed(delta, n as f64 / 6.0));
    assert!(
        (r.cd - analytic).abs() < 0.05 * analytic,
        "cd {} vs {analytic}",
        r.cd
    );
    // Dilation: the output is outside the closed source by ≈ 0.005 × 200 = 1 voxel.
    let offset = r.offset_voxels.unwrap_or(f64::NAN);
    let expected_offset = out_to_src * resolution as f64;
    assert!(
        (offset - expected_offset).abs() < 0.005 * expected_offset,
        "offset {offset} vs {expected_offset}"
    );
    assert_eq!(r.output_to_source_voxels, offset);
    // Faces are parallel to their counterparts; only pairs across cube edges disagree.
    assert!(r.anc > 98.0 && r.anc < 100.0, "anc {}", r.anc);
}

#[test]
fn shrunk_output_has_a_negative_offset() {
    let source = cube([0.0; 3], 1.0, false);
    let smaller = map(&source, |p| p.map(|x| x * 0.99));
    let r = eval(&source, &smaller, options(20_000, 200));
    let offset = r.offset_voxels.unwrap_or(f64::NAN);
    // Every output point is 0.005 inside a face: −1 voxel.
    assert!((offset + 1.0).abs() < 1e-6, "offset {offset}");
    assert!((r.output_to_source_voxels - 1.0).abs() < 1e-6);
}

#[test]
fn small_translation_is_the_chamfer_distance() {
    let source = cube([0.0; 3], 1.0, false);
    let t = 1e-4f32;
    let moved = map(&source, |p| [p[0] + t, p[1], p[2]]);
    let r = eval(&source, &moved, options(20_000, 256));
    let t = t as f64;
    // Same samples moved by t; every other sample is a sample spacing (≫ t) away.
    assert!((r.cd - t).abs() < 0.01 * t, "cd {} vs {t}", r.cd);
    // To the surface only the two x faces are off, by t: a third of the area.
    assert!(
        (r.cd_surface - t / 3.0).abs() < 0.02 * t,
        "cd_surface {} vs {}",
        r.cd_surface,
        t / 3.0
    );
    for f in &r.f1 {
        assert_eq!(f.f1, 100.0, "F1 at {}", f.threshold);
    }
}

#[test]
fn dropping_one_of_two_cubes_keeps_one_component() {
    let a = cube([-1.0, 0.0, 0.0], 1.0, false);
    let b = cube([1.0, 0.0, 0.0], 0.5, false);
    let both = merge(&a, &b);
    let r = eval(&both, &a, options(20_000, 64));
    assert_eq!(r.source_components, 2);
    assert_eq!((r.components_kept, r.components_total), (1, 2));
    let r = eval(&both, &both, options(20_000, 64));
    assert_eq!((r.components_kept, r.components_total), (2, 2));
}

#[test]
fn components_below_two_voxels_are_not_counted() {
    let big = cube([0.0; 3], 1.0, false);
    // 0.01 of the longest side is 0.64 voxel at N = 64.
    let speck = cube([0.9, 0.0, 0.0], 0.01, false);
    let r = eval(&merge(&big, &speck), &big, options(20_000, 64));
    assert_eq!(r.source_components, 2);
    assert_eq!((r.components_kept, r.components_total), (1, 1));
}

#[test]
fn open_source_has_no_offset() {
    let mut sheet = TriMesh::default();
    push_quad(
        &mut sheet,
        &[[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]],
        false,
    );
    let r = eval(&sheet, &sheet, options(10_000, 64));
    assert!(!r.source_closed && !r.output_closed);
    assert_eq!(r.offset_voxels, None);
    assert_eq!((r.components_kept, r.components_total), (1, 1));
}

#[test]
fn empty_output_and_zero_samples_are_errors() {
    let mesh = cube([0.0; 3], 1.0, false);
    assert!(evaluate(&mesh, &TriMesh::default(), &options(1000, 64)).is_err());
    assert!(evaluate(&mesh, &mesh, &options(0, 64)).is_err());
    let bad = TriMesh::new(vec![[0.0; 3]], vec![[0, 1, 2]]);
    assert!(evaluate(&mesh, &bad, &options(1000, 64)).is_err());
}

#[test]
fn same_numbers_with_one_or_two_threads() {
    let source = merge(
        &cube([0.0; 3], 1.0, false),
        &cube([2.0, 0.5, 0.0], 0.7, true),
    );
    let output = map(&cube([0.01, 0.0, 0.0], 1.02, true), |p| {
        [p[0], p[1] * 0.99, p[2]]
    });
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap_or_else(|e| panic!("thread pool: {e}"));
        pool.install(|| eval(&source, &output, options(30_000, 128)))
    };
    assert_eq!(run(1), run(2));
}
