//! A job from before sharp-near samples existed draws and stores the same bytes: the samples of
//! its parameters and the content digest of a row holding them are pinned to the values the
//! build before the change computed (d914a6e), on two bundled meshes.

use sparc3d_schema::{ErrorClass, RowTensors, SampleTensors, ShardRow};
use sparcubes::samples::{sample, Precision, SampleParams, Samples};

/// FNV-1a over the little-endian bytes of `bits`.
fn fnv(h: &mut u64, bits: u64) {
    for b in bits.to_le_bytes() {
        *h ^= b as u64;
        *h = h.wrapping_mul(0x100000001b3);
    }
}

/// A hash of every sample column the build before drew, in its order.
fn samples_hash(s: &Samples) -> u64 {
    let mut h = 0xcbf29ce484222325u64;
    for v in [
        &s.surface_points,
        &s.surface_normals,
        &s.sharp_points,
        &s.sharp_normals,
        &s.near_points,
        &s.volume_points,
    ] {
        fnv(&mut h, v.len() as u64);
        for c in v.iter().flatten() {
            fnv(&mut h, c.to_bits() as u64);
        }
    }
    for v in [&s.near_sdf, &s.volume_sdf] {
        fnv(&mut h, v.len() as u64);
        for c in v {
            fnv(&mut h, c.to_bits() as u64);
        }
    }
    for o in &s.volume_occupancy {
        fnv(&mut h, *o as u64);
    }
    h
}

/// The sample parameters of a stored job of that build (its defaults, fewer points).
fn stored_params() -> SampleParams {
    SampleParams {
        surface: 2000,
        sharp: 2000,
        near: 3000,
        sharp_near: 0,
        volume: 3000,
        near_sigmas: vec![0.005, 0.05],
        sharp_near_sigmas: Vec::new(),
        near_bound: 0.25,
        volume_bound: 1.05,
        sharp_angle_deg: 15.0,
        dtype: Precision::F16,
        seed: 3,
    }
}

#[test]
fn samples_and_digest_of_a_job_from_before_are_unchanged() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    let pins = [
        (
            "wuson.stl",
            40,
            0x757bfc1e689d25d1u64,
            "f22619171f899f9d4e7b7e1153f15aae9c309e3dbe17116b9e44aa6809661624",
        ),
        (
            "cube.off",
            32,
            0x55e0fa4607891a83,
            "e2688d4902ae6405205017a6ec9c7ccbce0b993ba1715baa9ae02b41202feb90",
        ),
    ];
    for (file, resolution, hash, digest) in pins {
        let loaded = sparcubes::io::load(&root.join(file)).unwrap_or_else(|e| panic!("{e}"));
        let params = sparcubes::Params::with_resolution(resolution);
        let cubes = sparcubes::convert(&loaded.mesh, &params)
            .unwrap_or_else(|e| panic!("{e}"))
            .cubes;
        let mesh = sparcubes::extract(&cubes);
        let s = sample(&cubes, &mesh, &stored_params()).unwrap_or_else(|e| panic!("{e}"));
        assert!(s.sharp_near_points.is_empty() && s.sharp_near_sdf.is_empty());
        assert_eq!(samples_hash(&s), hash, "{file}: samples");
        let mut tensors = RowTensors::from_cubes(&cubes, 3).unwrap_or_else(|e| panic!("{e}"));
        let encoded = SampleTensors::from_samples(&s, &stored_params(), 3);
        tensors.samples = Some(encoded.unwrap_or_else(|e| panic!("{e}")));
        let mut row = ShardRow::failed(
            0,
            "a",
            "a.obj",
            resolution,
            ErrorClass::Geometry(sparcubes::ErrorClass::ParseError),
            "x".into(),
        );
        row.tensors = Some(tensors);
        assert_eq!(
            sparc3d_schema::row::digest::rows_digest(&[row]),
            digest,
            "{file}: digest"
        );
    }
}
