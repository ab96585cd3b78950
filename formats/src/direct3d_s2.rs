//! Direct3D-S2's sparse SDF (`SparseSDFVAE.encode`, `direct3d_s2/models/autoencoders/ss_vae.py`
//! L75-91 of DreamTechAI/Direct3D-S2: `sparse_index` [N, 3], `sparse_sdf` [N, 1]), computed
//! from the stored grid as its truncated signed distance
//! ([`sparcubes::products::truncated_sdf`]) at [`TRUNCATION`]: the grid points within 4
//! voxels of the surface, signed distance / 4 voxels, positive outside.
//!
//! Frame: its `sparse2mesh` (ss_vae.py L107-129) fills a `res³` grid with +1 and puts index
//! `i` at `2i/res − 1` (L126), which is our normalized frame (`p = 2g/N − 1`) as it is; its
//! objects span ±0.95 of that cube (`normalize_mesh(mesh, scale=0.95)`, `utils/mesh.py`
//! L14-23). A job converted with `params.object_span = 0.95` has its object's longest side on
//! exactly ±0.95, centred up to the grid's sub-voxel shift (`GRID_OFFSET`, under 0.04 voxel),
//! so the indices are written as they are, with no resampling. Any other job is refused in the
//! consumer frame ([`check`]); `--frame normalized` writes it in the job's own frame.

use crate::spec::{grid_views, needs_no_samples, no_listing, PresetSpec, Reads, Spec, Views};
use crate::spec::{GridPreset, Settings};
use crate::{identity_arrays, npz::Array, npz_file, Frame, Item, ItemExport, JobCheck, Result};
use sparcubes::products::truncated_sdf::truncated_sdf;
use sparcubes::Params;

/// `--help` line.
pub const ABOUT: &str = "Direct3D-S2's sparse SDF: <item>.npz (sparse_index, sparse_sdf; a job with object_span = 0.95); checked against SparseSDFVAE.encode, sparse2mesh";

/// Direct3D-S2 as the export, `--for` and `--help` know it.
pub const SPEC: Spec = Spec {
    name: "direct3d-s2",
    title: "Direct3D-S2",
    about: ABOUT,
    frames: &[Frame::Consumer, Frame::Normalized],
    reads: Reads::CUBES,
    preset: Some(PresetSpec {
        help: "its span; N its resolution",
        samples: false,
        renders: None,
        grid: Some(GridPreset {
            form: "[@N]",
            required: false,
            accept: |_, _| Ok(()),
            params: |grid| Settings {
                resolution: grid,
                object_span: Some(OBJECT_SPAN),
                ..Settings::NONE
            },
            misfit: |_, _| None,
        }),
    }),
    missing: needs_no_samples,
    check,
    files,
    views: Views::Plain(grid_views),
    listing: no_listing,
};

/// The share of its cube Direct3D-S2's objects span: ±0.95 of [−1, 1] (`utils/mesh.py`
/// L14-23), the `params.object_span` a job needs for this export.
pub const OBJECT_SPAN: f64 = 0.95;

/// Direct3D-S2's truncation, in voxels: its `direct3d_s2/utils/mesh.py` keeps the points whose
/// unsigned distance is below 4 voxels (`compute_valid_udf(..., threshold=4.0)` then
/// `udf < 4 / size`), its decoder fills the rest of the grid with 1 (outside) before marching
/// cubes, and its authors state that the truncated SDF is normalised to [−1, 1] for input and
/// supervision (issue #34 of that repository).
pub const TRUNCATION: f64 = 4.0;

/// The resolutions of Direct3D-S2's two sparse VAEs (`pipeline.py` L26-29, L126-137).
pub const RESOLUTIONS: [u32; 2] = [512, 1024];

/// The preset `--for` takes to make a job for Direct3D-S2 at `resolution`: `direct3d-s2@N`
/// at one of its [`RESOLUTIONS`], else `direct3d-s2` (its span alone).
fn preset_name(resolution: u32) -> String {
    let name = SPEC.name;
    match RESOLUTIONS.contains(&resolution) {
        true => format!("{name}@{resolution}"),
        false => name.to_string(),
    }
}

/// In the consumer frame, a job must have been converted with `params.object_span = 0.95`
/// (refused otherwise); a resolution other than 512 or 1024 is written with a warning.
pub fn check(params: &Params, frame: Frame) -> JobCheck {
    let mut out = JobCheck::default();
    if frame == Frame::Consumer && params.object_span != Some(OBJECT_SPAN) {
        out.required.push(format!(
            "params.object_span = {OBJECT_SPAN} (Direct3D-S2's objects span ±0.95 of its cube; \
             this job's span {:.6} of the grid): make the job with --for {}; or export with \
             --frame normalized to write the job's own frame",
            params.span(),
            preset_name(params.resolution)
        ));
    }
    if !RESOLUTIONS.contains(&params.resolution) {
        out.warnings.push(format!(
            "resolution {} is neither 512 nor 1024, the grids Direct3D-S2's sparse VAEs read",
            params.resolution
        ));
    }
    out
}

/// One `<stem>.npz` with `sparse_index` and `sparse_sdf` (and `frame`). Grid points at index
/// N (the grid's upper faces) are left out: `sparse2mesh` has no such point (its grid is
/// `res³`, indices 0..res), and they are outside and at least 3 voxels from the object (the
/// job's margin), where its fill value +1 has the right sign.
pub fn files(item: &Item) -> Result<ItemExport> {
    let n = item.cubes.resolution;
    let s = truncated_sdf(item.cubes, TRUNCATION);
    let (index, sdf): (Vec<[i32; 3]>, Vec<f32>) = s
        .coords
        .iter()
        .zip(&s.sdf)
        .filter(|(c, _)| c.iter().all(|&v| u32::from(v) < n))
        .map(|(c, &d)| (c.map(i32::from), d))
        .unzip();
    let flat: Vec<i32> = index.iter().flatten().copied().collect();
    let mut arrays = identity_arrays(item);
    arrays.extend([
        Array::numbers("sparse_index", "<i4", vec![index.len(), 3], &flat),
        Array::numbers("sparse_sdf", "<f4", vec![sdf.len(), 1], &sdf),
        Array::text("frame", item.frame.name()),
    ]);
    Ok(ItemExport {
        files: vec![npz_file(format!("{}.npz", item.stem), &arrays)?],
        ..Default::default()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_consumer_frame_needs_the_span_of_its_cube() {
        let mut p = Params::with_resolution(512);
        let c = check(&p, Frame::Consumer);
        assert!(
            c.required[0].starts_with("params.object_span = 0.95"),
            "{c:?}"
        );
        assert!(c.required[0].contains("--for direct3d-s2@512"), "{c:?}");
        assert!(check(&p, Frame::Normalized).required.is_empty());
        p.object_span = Some(0.95);
        assert_eq!(check(&p, Frame::Consumer), JobCheck::default());
        p.resolution = 128;
        assert_eq!(check(&p, Frame::Consumer).warnings.len(), 1);
    }

    #[test]
    fn the_preset_named_is_one_that_parses_and_fits_the_grid() {
        for (resolution, name) in [(512, "direct3d-s2@512"), (128, "direct3d-s2")] {
            assert_eq!(preset_name(resolution), name);
            let parsed = crate::preset::Preset::parse(name).map(|p| p.name());
            assert_eq!(parsed.ok().as_deref(), Some(name));
        }
    }
}
