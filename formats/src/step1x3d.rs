//! Step1X-3D (stepfun-ai/Step1X-3D, read at 20b5de2): `surfaces/<stem>.npz` per item, listed
//! by stem in `train.json`, what `step1x3d_geometry/data/base.py` (`BaseDataset`,
//! `_load_shape_from_occupancy_or_sdf` L104-159, `_load_shape_supervision_occupancy_or_sdf`
//! L161-202) reads: `surface` and `sharp_surface` `[N, 6]` (xyz + normal; it picks sharp rows
//! by the surface's indices, L126, so both hold [`SURFACE_ROWS`]), `near_surface_points` and
//! `volume_rand_points` `[·, 4]` (xyz + sdf) and `bounds`. Its repository has no producer and
//! points to Dora's (README L75), so the samples follow Dora's recipe ([`crate::dora`]): near
//! points at σ 0.001 and 0.005, volume points in ±1.05, `float32`, the distance **positive
//! inside** (its occupancy is `sdf ≥ 1e-3`, L186-188), the frame Dora's (longest side ±1).

use crate::arrays::{floats, point_normal_rows, Width};
use crate::dora::{self, near_and_volume, near_and_volume_needs, signed_rows};
use crate::select::{require_sharp, samples_off, unmet, Need};
use crate::{npz::Array, npz_file, ExportFile, Item, ItemExport, Listed, Result};
use sparcubes::samples::SampleParams;

/// `--help` line.
pub const ABOUT: &str =
    "Step1X-3D: surfaces/<item>.npz (surface, sharp_surface, near_surface_points, volume_rand_points; f32, sdf > 0 inside) + train/val/test.json; checked against step1x3d_geometry/data/base.py BaseDataset";

/// Rows of `surface` and of `sharp_surface`.
const SURFACE_ROWS: usize = 124_928;

/// The `[samples]` counts it needs.
pub fn missing(samples: Option<&SampleParams>) -> Vec<String> {
    let Some(p) = samples else {
        return samples_off();
    };
    let mut needs = vec![
        Need::rows("surface", p.surface, SURFACE_ROWS),
        Need::rows("sharp", p.sharp, SURFACE_ROWS),
    ];
    needs.extend(near_and_volume_needs(p));
    unmet(&needs)
}

/// The item's `surfaces/<stem>.npz`.
pub fn files(item: &Item) -> Result<ItemExport> {
    let stored = item.stored_samples()?;
    let (s, p) = (stored.samples, stored.params);
    require_sharp(s, p.sharp_angle_deg, SURFACE_ROWS, "Step1X-3D")?;
    let place = item.placement(dora::HALF_EXTENT);
    let n = SURFACE_ROWS.min(s.surface_points.len());
    let (near, volume) = near_and_volume(s, p, &item.consumer_cube(dora::HALF_EXTENT))?;
    let mut arrays = crate::identity_arrays(item);
    arrays.extend([
        floats(
            "surface",
            vec![n, 6],
            &point_normal_rows(&s.surface_points[..n], &s.surface_normals[..n], &place),
            Width::F32,
        ),
        floats(
            "sharp_surface",
            vec![n, 6],
            &point_normal_rows(&s.sharp_points[..n], &s.sharp_normals[..n], &place),
            Width::F32,
        ),
        floats(
            "near_surface_points",
            vec![near.len(), 4],
            &signed_rows(&s.near_points, &s.near_sdf, &near, &place),
            Width::F32,
        ),
        floats(
            "volume_rand_points",
            vec![volume.len(), 4],
            &signed_rows(&s.volume_points, &s.volume_sdf, &volume, &place),
            Width::F32,
        ),
        Array::numbers("bounds", "<f4", vec![], &[dora::VOLUME_BOUND as f32]),
    ]);
    Ok(ItemExport {
        files: vec![npz_file(format!("surfaces/{}.npz", item.stem), &arrays)?],
        ..Default::default()
    })
}

/// `train.json`, `val.json` and `test.json` (as Dora's, [`dora::split_lists`]): the items'
/// stems (its uids).
pub fn listing(items: &[Listed]) -> Result<Vec<ExportFile>> {
    dora::split_lists(items, |l| vec![l.stem.clone()])
}
