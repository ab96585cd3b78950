//! Dora (Seed3D/Dora, read at a166e21): one `float32` `<stem>.npz` per item as
//! `sharp_edge_sampling/sharp_sample.py` (`process_mesh`, L37-270) writes it, listed in
//! `train.json`, what `craftsman/data/objaverse.py` (`ObjaverseDataset._load_shape` L121-164,
//! `_load_shape_supervision` L166-210) reads:
//!
//! - `fps_coarse_surface` `[32768, 1, 6]`: farthest-point samples of the surface points (xyz +
//!   normal; Dora draws them from 200000 area-uniform points, L224-233, we from ours);
//! - `fps_sharp_surface` `[32768, 1, 6]`: the same of the sharp-edge points (L235-244);
//! - `sharp_near_surface` `[131072, 4]`: sharp-edge points moved at σ 0.001, 0.005, 0.007,
//!   0.01 (32768 each, L194-205), with their signed distance;
//! - `rand_points` `[400000 + v, 4]`: 200000 near points at σ 0.001, 200000 at σ 0.005, then
//!   `v` uniform in ±1.05 (L208-222); its loader takes the first 400000 rows as near and the
//!   rest as volume, so the order is fixed. `v` is 200000 as its producer writes where the job's
//!   volume samples that fall in ±1.05 of Dora's cube are that many (at 256³ and finer with the
//!   defaults), else all of them (its loader draws 10000; at 64³ the job's volume cube maps to
//!   ±1.16 and about 186000 fall inside).
//!
//! Distances are **positive inside** (pysdf's sign), in its frame: the bounding box centred,
//! its longest side onto ±1 (`to_watertight_mesh.py` `remesh` L48-54). A mesh without a sharp
//! edge gets no file, as its producer writes none (L257-258): the export counts it as left
//! out, not failed.
//! `train.json` lists the files by absolute path (its loader opens each entry as it is, L123),
//! `val.json` and `test.json` a few of them (`split_lists`).

use crate::arrays::{floats, point_distance_rows, point_normal_rows, Width};
use crate::select::{
    block_needs, block_rows, missing_needs, require_sharp, rows_in_cube, sharp_near_needs,
    sharp_near_rows, surface_and_sharp_needs, Need,
};
use crate::spec::{takes_any_job, PresetSpec, Reads, Spec, Views};
use crate::Frame;
use crate::{npz::Array, npz_file, Error, ExportFile, Item, ItemExport, Listed, Placement, Result};
use sparcubes::samples::{farthest_points, SampleParams, Samples};
use std::path::Path;

/// `--help` line.
pub const ABOUT: &str =
    "Dora: <item>.npz (fps_coarse_surface, fps_sharp_surface, sharp_near_surface, rand_points; f32, sdf > 0 inside) + train/val/test.json; checked against craftsman/data/objaverse.py ObjaverseDataset";

/// Dora as the export, `--for` and `--help` know it.
pub const SPEC: Spec = Spec {
    name: "dora",
    title: "Dora",
    about: ABOUT,
    frames: &Frame::ALL,
    reads: Reads::SAMPLES,
    preset: Some(PresetSpec::SAMPLES),
    missing,
    check: takes_any_job,
    files,
    views: Views::Plain(|item| item.placement(HALF_EXTENT)),
    listing,
};

/// Farthest-point samples per surface kind (`point_number // 2`, L123, README's 65536).
const FPS_ROWS: usize = 32_768;
/// The sharp-near blocks, σ 0.001, 0.005, 0.007, 0.01, each [`FPS_ROWS`] rows (L194-205).
const SHARP_NEAR_BLOCKS: [(f64, usize); 4] = [
    (0.001, FPS_ROWS),
    (0.005, FPS_ROWS),
    (0.007, FPS_ROWS),
    (0.01, FPS_ROWS),
];
/// The two near blocks of `rand_points`, σ 0.001 and 0.005 (L208-222).
const NEAR_BLOCKS: [(f64, usize); 2] = [(0.001, NEAR_BLOCK), (0.005, NEAR_BLOCK)];
/// Rows of each near block, and most rows of the volume block (L208-222).
pub(crate) const NEAR_BLOCK: usize = 200_000;
/// Fewest rows of the volume block: what its loader draws from it without replacement
/// (`n_supervision[2]`, `configs/shape-autoencoder/Dora-VAE-train.yaml` L7-14).
pub(crate) const VOLUME_LEAST: usize = 10_000;
/// Half side of the volume cube.
pub(crate) const VOLUME_BOUND: f64 = 1.05;
/// Half extent of the longest side in its frame.
pub const HALF_EXTENT: f64 = 1.0;

/// The `[samples]` counts it needs.
pub fn missing(samples: Option<&SampleParams>) -> Vec<String> {
    missing_needs(samples, |p| {
        let mut needs = surface_and_sharp_needs(p, FPS_ROWS);
        needs.extend(near_and_volume_needs(p));
        needs.extend(sharp_near_needs(p, &SHARP_NEAR_BLOCKS));
        needs
    })
}

/// What Dora's near and volume blocks need (Step1X-3D follows the same recipe).
pub(crate) fn near_and_volume_needs(p: &SampleParams) -> Vec<Need> {
    let mut needs = block_needs("near", p.near, &p.near_sigmas, &NEAR_BLOCKS);
    needs.push(Need::rows("volume", p.volume, VOLUME_LEAST));
    needs
}

/// The item's `<stem>.npz`.
pub fn files(item: &Item) -> Result<ItemExport> {
    let stored = item.stored_samples()?;
    let (s, p) = (stored.samples, stored.params);
    require_sharp(s, FPS_ROWS, "Dora")?;
    let place = item.placement(HALF_EXTENT);
    let fps = |points: &[[f32; 3]], normals: &[[f32; 3]], name: &str| {
        let picked = farthest_points(points, FPS_ROWS);
        let pts: Vec<[f32; 3]> = picked.iter().map(|&i| points[i as usize]).collect();
        let nrm: Vec<[f32; 3]> = picked.iter().map(|&i| normals[i as usize]).collect();
        floats(
            name,
            vec![pts.len(), 1, 6],
            &point_normal_rows(&pts, &nrm, &place),
            Width::F32,
        )
    };
    let sharp_near = sharp_near_rows(s, p, &SHARP_NEAR_BLOCKS)?;
    let (near, volume) = near_and_volume(s, p, &item.consumer_cube(HALF_EXTENT))?;
    let mut rand = signed_rows(&s.near_points, &s.near_sdf, &near, &place);
    rand.extend(signed_rows(
        &s.volume_points,
        &s.volume_sdf,
        &volume,
        &place,
    ));
    let mut arrays = crate::identity_arrays(item);
    arrays.extend([
        fps(&s.surface_points, &s.surface_normals, "fps_coarse_surface"),
        fps(&s.sharp_points, &s.sharp_normals, "fps_sharp_surface"),
        signed_array(
            "sharp_near_surface",
            (&s.sharp_near_points, &s.sharp_near_sdf),
            &sharp_near,
            &place,
        ),
        floats(
            "rand_points",
            vec![near.len() + volume.len(), 4],
            &rand,
            Width::F32,
        ),
    ]);
    Ok(ItemExport {
        files: vec![npz_file(format!("{}.npz", item.stem), &arrays)?],
        ..Default::default()
    })
}

/// `train.json`, `val.json` and `test.json` (`split_lists`): the absolute paths of the
/// items' files.
pub fn listing(items: &[Listed], root: &Path) -> Result<Vec<ExportFile>> {
    split_lists(items, |l| {
        // Its data module opens every entry as an item's npz: the views beside are not one.
        l.files
            .iter()
            .filter(|f| !f.starts_with(crate::renders::PLAIN_DIR))
            .map(|f| root.join(f).to_string_lossy().into_owned())
            .collect()
    })
}

/// Items in `val.json` and `test.json`, at most.
pub(crate) const CHECK_ITEMS: usize = 16;

/// The split lists Dora's and Step1X-3D's data modules open: `train.json` with every item's
/// `entries`, and `val.json` and `test.json` with those of the [`CHECK_ITEMS`] items of
/// smallest id (ids are content hashes, so a fair draw that stays put as a job grows), in item
/// order. Both data modules build a `val` split when training starts and their launch scripts
/// run `test` after it (Dora `craftsman/data/objaverse.py` L246-247 and `launch.py` L263-264;
/// Step1X-3D `step1x3d_geometry/data/Objaverse.py` L40-43 and `train.py` L288-289), so a
/// missing file stops a run. They are for those checks, not held out: they stay in
/// `train.json`.
pub(crate) fn split_lists(
    items: &[Listed],
    entries: impl Fn(&Listed) -> Vec<String>,
) -> Result<Vec<ExportFile>> {
    let all: Vec<String> = items.iter().flat_map(&entries).collect();
    let mut by_id: Vec<usize> = (0..items.len()).collect();
    by_id.sort_by(|&a, &b| items[a].id.cmp(&items[b].id));
    by_id.truncate(CHECK_ITEMS);
    by_id.sort_unstable();
    let checks: Vec<String> = by_id.iter().flat_map(|&i| entries(&items[i])).collect();
    Ok(vec![
        json_list("train.json", &all)?,
        json_list("val.json", &checks)?,
        json_list("test.json", &checks)?,
    ])
}

/// A JSON list of strings as a file.
pub(crate) fn json_list(path: &str, entries: &[String]) -> Result<ExportFile> {
    let bytes =
        serde_json::to_vec_pretty(entries).map_err(|e| Error::Invalid(format!("{path}: {e}")))?;
    Ok(ExportFile {
        path: path.into(),
        bytes,
    })
}

/// The rows of Dora's near blocks (σ 0.001, then σ 0.005) and of its volume block (inside
/// ±1.05 of its cube, `cube`).
pub(crate) fn near_and_volume(
    s: &Samples,
    p: &SampleParams,
    cube: &Placement,
) -> Result<(Vec<usize>, Vec<usize>)> {
    let near = block_rows(s.near_points.len(), &p.near_sigmas, &NEAR_BLOCKS, "near")?;
    let volume = rows_in_cube(&s.volume_points, cube, VOLUME_BOUND, NEAR_BLOCK);
    if volume.len() < VOLUME_LEAST {
        return Err(Error::Missing(format!(
            "{} volume points inside ±{VOLUME_BOUND}, {VOLUME_LEAST} needed (raise samples.volume)",
            volume.len()
        )));
    }
    Ok((near, volume))
}

/// The `[n, 4]` f32 array `name` of [`signed_rows`]: the chosen rows of `(points, sdf)`.
pub(crate) fn signed_array(
    name: &str,
    (points, sdf): (&[[f32; 3]], &[f32]),
    rows: &[usize],
    place: &Placement,
) -> Array {
    floats(
        name,
        vec![rows.len(), 4],
        &signed_rows(points, sdf, rows, place),
        Width::F32,
    )
}

/// Rows `[x, y, z, sdf]` of the chosen points, the distance positive inside.
pub(crate) fn signed_rows(
    points: &[[f32; 3]],
    sdf: &[f32],
    rows: &[usize],
    place: &Placement,
) -> Vec<f64> {
    let pts: Vec<[f32; 3]> = rows.iter().map(|&i| points[i]).collect();
    let d: Vec<f32> = rows.iter().map(|&i| sdf[i]).collect();
    point_distance_rows(&pts, &d, place, -1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;
    use std::path::PathBuf;

    #[test]
    fn val_and_test_hold_the_items_of_smallest_id_in_item_order() {
        // 20 items whose ids do not follow their order.
        let items: Vec<Listed> = (0..20u32)
            .map(|i| Listed {
                id: format!("{:02}", (i * 7) % 20),
                stem: format!("s{i}"),
                files: vec![PathBuf::from(format!("s{i}.npz"))],
                columns: BTreeMap::new(),
                provenance: BTreeMap::new(),
            })
            .collect();
        let files = split_lists(&items, |l| vec![l.stem.clone()]).unwrap_or_default();
        let read = |k: usize| -> Vec<String> {
            serde_json::from_slice(&files[k].bytes).unwrap_or_default()
        };
        let names: Vec<_> = files.iter().map(|f| f.path.clone()).collect();
        assert_eq!(
            names,
            ["train.json", "val.json", "test.json"].map(PathBuf::from)
        );
        assert_eq!(read(0).len(), 20);
        let val = read(1);
        assert_eq!(val, read(2));
        let expected: Vec<String> = (0..20u32)
            .filter(|i| (i * 7) % 20 < CHECK_ITEMS as u32)
            .map(|i| format!("s{i}"))
            .collect();
        assert_eq!(val, expected);
    }
}
