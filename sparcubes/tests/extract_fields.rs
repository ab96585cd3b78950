//! Extraction of analytic and random fields: the result must always be a closed, 2-manifold,
//! consistently oriented mesh with the inside on the negative side, close to the analytic
//! surface, and the same bytes on every run.

use sparcubes::extract::{extract, extract_to_source, sample_box};
use sparcubes::topology::{check, TopologyReport};
use sparcubes::{SparseCubes, TriMesh};

/// A small deterministic generator (SplitMix64).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn f(c: [u16; 3]) -> [f64; 3] {
    [c[0] as f64, c[1] as f64, c[2] as f64]
}

fn dist(p: [f64; 3], q: [f64; 3]) -> f64 {
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
}

fn euler(mesh: &TriMesh) -> i64 {
    let mut edges: Vec<(u32, u32)> = mesh
        .triangles
        .iter()
        .flat_map(|t| (0..3).map(move |i| (t[i].min(t[(i + 1) % 3]), t[i].max(t[(i + 1) % 3]))))
        .collect();
    edges.sort_unstable();
    edges.dedup();
    let mut used: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    used.sort_unstable();
    used.dedup();
    used.len() as i64 - edges.len() as i64 + mesh.triangles.len() as i64
}

fn assert_closed(report: &TopologyReport, what: &str) {
    assert!(report.is_watertight(), "{what}: not watertight: {report:?}");
    assert!(report.is_manifold(), "{what}: not manifold: {report:?}");
    assert_eq!(
        report.inconsistently_oriented_edges, 0,
        "{what}: {report:?}"
    );
}

fn field_cubes(n: u16, sdf: impl Fn([f64; 3]) -> f64 + Sync) -> SparseCubes {
    sample_box(n as u32, [0; 3], [n; 3], |c| (sdf(f(c)) as f32, [0.0; 3]))
}

#[test]
fn sphere_is_closed_and_on_the_radius() {
    let centre = [16.3, 16.1, 15.8];
    let r = 10.0;
    let cubes = field_cubes(32, |p| dist(p, centre) - r);
    let mesh = extract(&cubes);
    let report = check(&mesh);
    assert_closed(&report, "sphere");
    assert_eq!(report.components, 1);
    assert_eq!(euler(&mesh), 2);
    for p in &mesh.positions {
        let d = dist([p[0] as f64, p[1] as f64, p[2] as f64], centre);
        assert!((d - r).abs() < 0.05, "vertex at radius {d}");
    }
    let v = mesh.signed_volume();
    let exact = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
    assert!((v - exact).abs() / exact < 0.02, "volume {v} vs {exact}");
}

#[test]
fn torus_has_genus_one() {
    let c = [16.2, 15.7, 16.4];
    let (big, small) = (9.0, 3.5);
    let cubes = field_cubes(32, |p| {
        let q = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
        let ring = (q[0] * q[0] + q[1] * q[1]).sqrt() - big;
        (ring * ring + q[2] * q[2]).sqrt() - small
    });
    let mesh = extract(&cubes);
    let report = check(&mesh);
    assert_closed(&report, "torus");
    assert_eq!(report.components, 1);
    assert_eq!(euler(&mesh), 0);
    let exact = 2.0 * std::f64::consts::PI.powi(2) * big * small * small;
    let v = mesh.signed_volume();
    assert!((v - exact).abs() / exact < 0.03, "volume {v} vs {exact}");
}

#[test]
fn two_nearby_spheres_stay_apart() {
    // A gap of 1.3 voxels: every grid line between them has an outside vertex.
    let (a, b) = ([10.2, 16.1, 16.3], [23.5, 16.1, 16.3]);
    let cubes = field_cubes(32, |p| (dist(p, a) - 6.0).min(dist(p, b) - 6.0));
    let mesh = extract(&cubes);
    let report = check(&mesh);
    assert_closed(&report, "two spheres");
    assert_eq!(report.components, 2);
    assert_eq!(euler(&mesh), 4);
    assert!(mesh.signed_volume() > 0.0);
}

#[test]
fn thin_slab_is_one_closed_shell() {
    // A 20 × 20 × 1.5 voxel box, off the grid lines.
    let c = [16.1, 15.9, 16.37];
    let h = [10.0, 10.0, 0.75];
    let cubes = field_cubes(32, |p| {
        let q: [f64; 3] = std::array::from_fn(|i| (p[i] - c[i]).abs() - h[i]);
        let outside = q.map(|x| x.max(0.0));
        let o = (outside[0].powi(2) + outside[1].powi(2) + outside[2].powi(2)).sqrt();
        o + q[0].max(q[1]).max(q[2]).min(0.0)
    });
    let mesh = extract(&cubes);
    let report = check(&mesh);
    assert_closed(&report, "slab");
    assert_eq!(report.components, 1);
    assert_eq!(euler(&mesh), 2);
    let v = mesh.signed_volume();
    assert!((v - 600.0).abs() / 600.0 < 0.1, "slab volume {v}");
}

/// Random values on every vertex of a `cells`³ block, the outer layer outside, some exact
/// zeros; optional random deformation within ±`deform`.
fn random_cubes(seed: u64, cells: u16, p_inside: f32, deform: f32) -> SparseCubes {
    let n = cells;
    let mut rng = Rng(seed);
    let m = n as usize + 1;
    let mut values = vec![(0.0f32, [0.0f32; 3]); m * m * m];
    for (i, v) in values.iter_mut().enumerate() {
        let (x, y, z) = (i / (m * m), i / m % m, i % m);
        let border = [x, y, z].iter().any(|&a| a == 0 || a == m - 1);
        let r = rng.unit();
        let mag = rng.unit();
        let s = if border {
            mag
        } else if rng.unit() < 0.05 {
            0.0
        } else if r < p_inside {
            -mag - 1e-3
        } else {
            mag
        };
        let d = [(); 3].map(|_| (rng.unit() * 2.0 - 1.0) * deform);
        *v = (s, d);
    }
    sample_box(n as u32, [0; 3], [n; 3], |c| {
        values[(c[0] as usize * m + c[1] as usize) * m + c[2] as usize]
    })
}

fn check_random(deform: f32) {
    for seed in 0..240u64 {
        let p = [0.3, 0.5, 0.7][(seed % 3) as usize];
        let cubes = random_cubes(seed, 12, p, deform);
        let any_inside = cubes.sdf.iter().any(|&s| s < 0.0);
        let mesh = extract(&cubes);
        let report = check(&mesh);
        let what = format!("seed {seed} p {p} deform {deform}");
        assert_closed(&report, &what);
        assert_eq!(report.degenerate_faces, 0, "{what}");
        if any_inside {
            assert!(
                mesh.signed_volume() > 0.0,
                "{what}: volume {}",
                mesh.signed_volume()
            );
        } else {
            assert!(mesh.triangles.is_empty());
        }
    }
}

#[test]
fn random_sign_fields_are_always_closed_manifolds() {
    check_random(0.0);
}

#[test]
fn random_fields_with_deformation_are_always_closed_manifolds() {
    check_random(0.45);
}

#[test]
fn extraction_is_deterministic_across_thread_counts() {
    let centre = [32.3, 31.6, 32.2];
    let cubes = sample_box(64, [0; 3], [64; 3], |c| {
        let p = f(c);
        let d = (dist(p, centre) - 27.0) as f32;
        let w = [(p[0] * 0.37).sin() as f32 * 0.3, 0.1, -0.2];
        (d, w)
    });
    assert!(cubes.cells.len() > 3 * 4096, "several chunks");
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map(|pool| pool.install(|| extract(&cubes)))
            .unwrap_or_else(|e| panic!("pool: {e}"))
    };
    let one = run(1);
    let again = run(1);
    let four = run(4);
    assert_eq!(one, again);
    assert_eq!(one, four);
    assert_closed(&check(&one), "big sphere");
}

#[test]
fn extract_to_source_applies_the_normalization() {
    let mut cubes = field_cubes(16, |p| dist(p, [8.2, 7.9, 8.1]) - 4.0);
    cubes.normalization.center = [1.0, 2.0, 3.0];
    cubes.normalization.scale = 0.5;
    let grid = extract(&cubes);
    let source = extract_to_source(&cubes);
    assert_eq!(grid.triangles, source.triangles);
    for (g, s) in grid.positions.iter().zip(&source.positions) {
        let want = cubes.normalization.grid_to_source(g.map(f64::from), 16);
        for a in 0..3 {
            assert!((s[a] as f64 - want[a]).abs() < 1e-5);
        }
    }
}

#[test]
fn empty_and_inconsistent_inputs_do_not_panic() {
    let empty = SparseCubes::default();
    assert!(extract(&empty).triangles.is_empty());
    // A cell whose corners are missing is skipped.
    let mut cubes = field_cubes(8, |p| dist(p, [4.1, 4.2, 3.9]) - 2.0);
    cubes.cells.push([200, 200, 200]);
    cubes.cells.sort();
    let mesh = extract(&cubes);
    assert_closed(&check(&mesh), "with a dangling cell");
}
