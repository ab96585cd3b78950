//! Our own vector-set samples, one `<stem>.npz` per item: surface and sharp points with
//! normals, near and volume points with signed distances (negative inside) and the volume's
//! occupancy, in the job's normalized frame (the default; f16 when the job stores f16) or in
//! the source mesh's frame (f32). For readers of our own layout (`sparc3d_reader.iter_export`).

use crate::arrays::{floats, placed, Width};
use crate::npz::Array;
use crate::select::missing_needs;
use crate::spec::{no_listing, takes_any_job, PresetSpec, Reads, Spec, Views};
use crate::{identity_arrays, npz_file, Frame, Item, ItemExport, Placement, Result};
use sparcubes::samples::{Precision, SampleParams};

/// `--help` line.
pub const ABOUT: &str =
    "our vector-set samples: surface, sharp, near, volume (points, normals, signed distances); read by sparc3d_reader.iter_export";

/// Our vector-set layout as the export, `--for` and `--help` know it.
pub const SPEC: Spec = Spec {
    name: "vecset-npz",
    title: "sparc3d_reader",
    about: ABOUT,
    frames: &[Frame::Normalized, Frame::Source],
    reads: Reads::SAMPLES,
    preset: Some(PresetSpec::SAMPLES),
    missing,
    check: takes_any_job,
    files,
    views: Views::Plain(placement),
    listing: no_listing,
};

/// `samples.enabled` when the job draws no samples.
pub fn missing(samples: Option<&SampleParams>) -> Vec<String> {
    missing_needs(samples, |_| Vec::new())
}

/// Where the item's points are written: the source's frame, else the normalized one.
pub(crate) fn placement(item: &Item) -> Placement {
    match item.frame {
        Frame::Source => Placement::to_source(&item.cubes.normalization),
        _ => Placement::IDENTITY,
    }
}

/// One `<stem>.npz` with the item's samples in `item.frame`.
pub fn files(item: &Item) -> Result<ItemExport> {
    let s = item.stored_samples()?;
    let place = placement(item);
    let width = match item.frame {
        Frame::Source => Width::F32,
        _ => stored_width(s.params.dtype),
    };
    let points =
        |name: &str, v: &[[f32; 3]]| floats(name, vec![v.len(), 3], &placed(v, &place), width);
    let vectors = |name: &str, v: &[[f32; 3]]| {
        let flat: Vec<f64> = v.iter().flatten().map(|&x| x as f64).collect();
        floats(name, vec![v.len(), 3], &flat, width)
    };
    let distances = |name: &str, v: &[f32]| {
        let d: Vec<f64> = v.iter().map(|&x| place.distance(x)).collect();
        floats(name, vec![v.len()], &d, width)
    };
    let mut arrays = identity_arrays(item);
    arrays.extend([
        points("surface_points", &s.samples.surface_points),
        vectors("surface_normals", &s.samples.surface_normals),
        points("sharp_points", &s.samples.sharp_points),
        vectors("sharp_normals", &s.samples.sharp_normals),
        points("near_points", &s.samples.near_points),
        distances("near_sdf", &s.samples.near_sdf),
        points("volume_points", &s.samples.volume_points),
        distances("volume_sdf", &s.samples.volume_sdf),
        Array::numbers(
            "volume_occupancy",
            "|u1",
            vec![s.samples.volume_occupancy.len()],
            &s.samples.volume_occupancy,
        ),
    ]);
    // Only where the job draws them (not in jobs from before the kind existed).
    if s.params.sharp_near > 0 {
        arrays.extend([
            points("sharp_near_points", &s.samples.sharp_near_points),
            distances("sharp_near_sdf", &s.samples.sharp_near_sdf),
        ]);
    }
    arrays.push(Array::text("frame", item.frame.name()));
    Ok(ItemExport {
        files: vec![npz_file(format!("{}.npz", item.stem), &arrays)?],
        ..Default::default()
    })
}

/// The width the job stored its samples at.
fn stored_width(p: Precision) -> Width {
    match p {
        Precision::F16 => Width::F16,
        Precision::F32 => Width::F32,
    }
}
