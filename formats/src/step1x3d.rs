//! Step1X-3D (stepfun-ai/Step1X-3D, read at 20b5de2): `surfaces/<stem>.npz` per item, listed
//! by stem in `train.json`, what `step1x3d_geometry/data/base.py` (`BaseDataset`,
//! `_load_shape_from_occupancy_or_sdf` L104-159, `_load_shape_supervision_occupancy_or_sdf`
//! L161-202) reads: `surface` and `sharp_surface` `[N, 6]` (xyz + normal; it picks sharp rows
//! by the surface's indices, L126, so both hold `SURFACE_ROWS`), `near_surface_points` and
//! `volume_rand_points` `[·, 4]` (xyz + sdf) and `bounds`. Its repository has no producer and
//! points to Dora's (README L75), so the samples follow Dora's recipe ([`crate::dora`]): near
//! points at σ 0.001 and 0.005, volume points in ±1.05, `float32`, the distance **positive
//! inside** (its occupancy is `sdf ≥ 1e-3`, L186-188), the frame Dora's (longest side ±1).
//!
//! `sharp_surface` is read only where `with_sharp_data` is on (L108-110): its autoencoder
//! config `configs/train-geometry-autoencoder/michelangelo.yaml` has it off (L13), its
//! diffusion configs (`configs/train-geometry-diffusion/*.yaml`) on. An item without sharp
//! edges is written without `sharp_surface` ([`NO_SHARP`]), so the autoencoder trains on every
//! item and a `with_sharp_data: True` run stops at such an item with a `KeyError` naming the
//! key, never reads made-up rows; the export counts those items.

use crate::arrays::{floats, point_normal_rows, Width};
use crate::dora::{self, near_and_volume, near_and_volume_needs, signed_array};
use crate::renders::SourceToExport;
use crate::select::{has_sharp, missing_needs, surface_and_sharp_needs};
use crate::spec::{takes_any_job, PresetSpec, Reads, Spec, Views};
use crate::Frame;
use crate::{npz::Array, npz_file, ExportFile, Item, ItemExport, Listed, Result};
use sparcubes::samples::SampleParams;

/// `--help` line.
pub const ABOUT: &str =
    "Step1X-3D: surfaces/<item>.npz (surface, sharp_surface, near_surface_points, volume_rand_points; f32, sdf > 0 inside) + train/val/test.json, and with [renders] images/<item>/NNNN_rgb.png; checked against step1x3d_geometry/data/base.py BaseDataset";

/// Step1X-3D as the export, `--for` and `--help` know it.
pub const SPEC: Spec = Spec {
    name: "step1x-3d",
    title: "Step1X-3D",
    about: ABOUT,
    frames: &Frame::ALL,
    reads: Reads::SAMPLES,
    preset: Some(PresetSpec {
        renders: Some(RENDERS),
        ..PresetSpec::SAMPLES
    }),
    missing,
    check: takes_any_job,
    files,
    views: Views::Own,
    listing: |items, _| listing(items),
};

/// Rows of `surface` and of `sharp_surface`.
const SURFACE_ROWS: usize = 124_928;

/// The note of an item written without `sharp_surface` (the export counts them).
pub const NO_SHARP: &str = "without sharp_surface (no sharp edges): read by Step1X-3D's \
    autoencoder config (with_sharp_data: False), not by its with_sharp_data: True configs";

/// The `[samples]` counts it needs.
pub fn missing(samples: Option<&SampleParams>) -> Vec<String> {
    missing_needs(samples, |p| {
        let mut needs = surface_and_sharp_needs(p, SURFACE_ROWS);
        needs.extend(near_and_volume_needs(p));
        needs
    })
}

/// The item's `surfaces/<stem>.npz`.
pub fn files(item: &Item) -> Result<ItemExport> {
    let stored = item.stored_samples()?;
    let (s, p) = (stored.samples, stored.params);
    let place = item.placement(dora::HALF_EXTENT);
    let n = SURFACE_ROWS.min(s.surface_points.len());
    let (near, volume) = near_and_volume(s, p, &item.consumer_cube(dora::HALF_EXTENT))?;
    let rows = |name: &str, points: &[[f32; 3]], normals: &[[f32; 3]]| {
        floats(
            name,
            vec![n, 6],
            &point_normal_rows(&points[..n], &normals[..n], &place),
            Width::F32,
        )
    };
    let mut arrays = crate::identity_arrays(item);
    arrays.push(rows("surface", &s.surface_points, &s.surface_normals));
    let sharp = has_sharp(s, n);
    if sharp {
        arrays.push(rows("sharp_surface", &s.sharp_points, &s.sharp_normals));
    }
    arrays.extend([
        signed_array(
            "near_surface_points",
            (&s.near_points, &s.near_sdf),
            &near,
            &place,
        ),
        signed_array(
            "volume_rand_points",
            (&s.volume_points, &s.volume_sdf),
            &volume,
            &place,
        ),
        Array::numbers("bounds", "<f4", vec![], &[dora::VOLUME_BOUND as f32]),
    ]);
    let mut files = vec![npz_file(format!("surfaces/{}.npz", item.stem), &arrays)?];
    if let Some(r) = &item.renders {
        let dir = std::path::Path::new("images").join(item.stem);
        let to_export = SourceToExport::through(&place, &item.cubes.normalization);
        files.extend(crate::renders::files(r, &dir, to_export, &view_name)?);
    }
    Ok(ItemExport {
        files,
        note: (!sharp).then_some(NO_SHARP),
        ..Default::default()
    })
}

/// Step1X-3D's condition views: its render script is not released; its loader's paths name
/// 20 views (`0000` … `0019`, issue 61's reading of its data) and `_process_img` resizes each
/// to 512² (`base.py` L228), so TRELLIS's cameras, 20 of 512².
pub const RENDERS: crate::spec::RenderRecipe = crate::spec::RenderRecipe {
    recipe: "trellis",
    views: 20,
    size: 512,
};

/// The file of view `i` as `BaseDataset._load_image` reads it (`step1x3d_geometry/data/base.py`
/// L238-243: `images/<uid>/<i:04d>_rgb.png`, the uid being the item's stem here).
fn view_name(i: usize) -> String {
    format!("{i:04}_rgb.png")
}

/// `train.json`, `val.json` and `test.json` (as Dora's, `dora::split_lists`): the items'
/// stems (its uids).
pub fn listing(items: &[Listed]) -> Result<Vec<ExportFile>> {
    dora::split_lists(items, |l| vec![l.stem.clone()])
}
