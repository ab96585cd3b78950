//! TripoSG (VAST-AI-Research/TripoSG, read at fc5c409): `<stem>.npy` per item, a pickled dict
//! saved by `np.save`, what `scripts/inference_vae.py` (`load_surface`, L12-23) reads with
//! `np.load(path, allow_pickle=True).tolist()`: `surface_points` and `surface_normals`,
//! `float32 [N, 3]`, of which it draws 204800 rows without replacement (L18, L43-45; fewer
//! rows raise there). Its repository has no dataset code and no normalisation of this input;
//! it decodes in ±1.005 (L54), so the frame is the centred cube with the longest side on ±1.

use crate::arrays::placed;
use crate::pickle::{f32_rows, npy_of_object, Value};
use crate::select::{missing_needs, Need};
use crate::spec::{no_listing, takes_any_job, PresetSpec, Reads, Spec, Views};
use crate::Frame;
use crate::{Error, ExportFile, Item, ItemExport, Result};
use sparcubes::samples::SampleParams;

/// `--help` line.
pub const ABOUT: &str = "TripoSG: <item>.npy (pickled dict: surface_points, surface_normals; f32); checked against scripts/inference_vae.py load_surface";

/// TripoSG as the export, `--for` and `--help` know it.
pub const SPEC: Spec = Spec {
    name: "triposg",
    title: "TripoSG",
    about: ABOUT,
    frames: &Frame::ALL,
    reads: Reads::SAMPLES,
    preset: Some(PresetSpec::SAMPLES),
    missing,
    check: takes_any_job,
    files,
    views: Views::Plain(|item| item.placement(HALF_EXTENT)),
    listing: no_listing,
};

/// Rows its VAE script draws.
const SURFACE_ROWS: usize = 204_800;
/// Half extent of the longest side in its frame.
pub(crate) const HALF_EXTENT: f64 = 1.0;

/// The `[samples]` counts it needs.
pub fn missing(samples: Option<&SampleParams>) -> Vec<String> {
    missing_needs(samples, |p| {
        vec![Need::rows("surface", p.surface, SURFACE_ROWS)]
    })
}

/// The item's `<stem>.npy`.
pub fn files(item: &Item) -> Result<ItemExport> {
    let stored = item.stored_samples()?;
    let s = stored.samples;
    if s.surface_points.len() < SURFACE_ROWS {
        return Err(Error::Missing(format!(
            "{} surface points, TripoSG draws {SURFACE_ROWS}",
            s.surface_points.len()
        )));
    }
    let place = item.placement(HALF_EXTENT);
    let normals: Vec<f64> = s
        .surface_normals
        .iter()
        .flatten()
        .map(|&x| x as f64)
        .collect();
    let dict = Value::Dict(vec![
        (
            "surface_points".into(),
            f32_rows(&placed(&s.surface_points, &place), 3),
        ),
        ("surface_normals".into(), f32_rows(&normals, 3)),
        // The item it holds (its loader reads only the two keys above).
        ("id".into(), Value::Text(item.id.to_string())),
    ]);
    Ok(ItemExport {
        files: vec![ExportFile {
            path: format!("{}.npy", item.stem).into(),
            bytes: npy_of_object(&Value::ObjectArray(Box::new(dict))),
        }],
        ..Default::default()
    })
}
