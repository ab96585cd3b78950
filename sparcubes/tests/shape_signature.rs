//! The shape signature of converted meshes: copies of a shape moved, turned, scaled,
//! re-triangulated, mirrored or jittered stay within half the dedup threshold of the
//! original; distinct shapes of the same extent (a box and one 15 % longer, a cylinder, a
//! torus, a sphere) stay beyond twice it.

use sparcubes::products::shape_signature::{distance, shape_signature, ShapeSignature};
use sparcubes::{convert, extract, shapes, Params, TriMesh};

/// Resolution of the test conversions (the signature's noise falls as it grows: the
/// thresholds below hold with room here, and the default threshold was chosen at 256³).
const N: u32 = 96;
/// The dedup threshold `sparc3d dedup` uses by default (docs/QUALITY.md, "Near-duplicates").
const THRESHOLD: f64 = 0.03;

fn signature(mesh: &TriMesh) -> ShapeSignature {
    let cubes = convert(mesh, &Params::with_resolution(N))
        .expect("convert")
        .cubes;
    shape_signature(&extract(&cubes)).expect("a signature")
}

/// Turned about a skew axis, scaled by 3.7 and moved.
fn moved(mesh: &TriMesh) -> TriMesh {
    let n = 14f64.sqrt();
    shapes::similar(
        mesh,
        [1.0 / n, 2.0 / n, 3.0 / n],
        0.7,
        3.7,
        [10.0, -5.0, 2.0],
    )
}

fn originals() -> Vec<(&'static str, TriMesh)> {
    vec![
        (
            "slotted block",
            shapes::slotted_block([0.0; 3], [2.0, 1.2, 0.8], 0.3, 0.5),
        ),
        ("torus", shapes::torus([0.0; 3], 1.0, 0.35, 48)),
        ("box", shapes::cuboid([-1.0; 3], [1.0; 3], &[])),
    ]
}

#[test]
fn copies_of_a_shape_stay_within_the_threshold() {
    for (name, mesh) in originals() {
        let base = signature(&mesh);
        let copies = [
            ("moved", moved(&mesh)),
            ("retriangulated", shapes::split_at_centroids(&mesh)),
            (
                "mirrored and jittered",
                shapes::mirrored_jittered(&mesh, 0.002),
            ),
            (
                "all at once",
                shapes::mirrored_jittered(&shapes::split_at_centroids(&moved(&mesh)), 0.002),
            ),
        ];
        for (how, copy) in copies {
            let d = distance(&base, &signature(&copy));
            eprintln!("{name} {how}: {d:.4}");
            assert!(d < THRESHOLD / 2.0, "{name} {how}: distance {d}");
        }
    }
}

#[test]
fn distinct_shapes_of_one_extent_stay_apart() {
    let shapes = [
        ("box", shapes::cuboid([-1.0; 3], [1.0; 3], &[])),
        (
            "longer box",
            shapes::cuboid([-1.0; 3], [1.0, 1.0, 1.3], &[]),
        ),
        ("cylinder", shapes::cylinder([0.0; 2], 1.0, -1.0, 1.0, 64)),
        ("torus", shapes::torus([0.0; 3], 0.7, 0.3, 48)),
        ("sphere", shapes::sphere([0.0; 3], 1.0, 32)),
    ];
    let signatures: Vec<_> = shapes.iter().map(|(_, m)| signature(m)).collect();
    for i in 0..shapes.len() {
        for j in i + 1..shapes.len() {
            let d = distance(&signatures[i], &signatures[j]);
            eprintln!("{} vs {}: {d:.4}", shapes[i].0, shapes[j].0);
            assert!(
                d > 2.0 * THRESHOLD,
                "{} vs {}: distance {d}",
                shapes[i].0,
                shapes[j].0
            );
        }
    }
}

#[test]
fn the_signature_is_the_same_whatever_the_threads() {
    let mesh = moved(&shapes::torus([0.0; 3], 1.0, 0.35, 48));
    let cubes = convert(&mesh, &Params::with_resolution(N))
        .expect("convert")
        .cubes;
    let out = extract(&cubes);
    let with = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| shape_signature(&out)).expect("a signature")
    };
    let one = with(1);
    assert_eq!(one.map(f32::to_bits), with(3).map(f32::to_bits));
    assert_eq!(one.map(f32::to_bits), with(8).map(f32::to_bits));
    // The eigenvalue entries sum to their weight; the distributions end at or below 1.
    let sum: f32 = one[..3].iter().sum();
    assert!((sum - 2.0).abs() < 1e-4, "{one:?}");
    assert!(
        one[4..].iter().all(|&x| (0.0..=1.0 + 1e-6).contains(&x)),
        "{one:?}"
    );
}
