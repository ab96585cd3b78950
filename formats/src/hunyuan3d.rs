//! Hunyuan3D-2.1 (Tencent-Hunyuan/Hunyuan3D-2.1, read at 5e3ec6d): per item the folder
//! `<stem>/geo_data/` with the two files `hy3dshape/tools/watertight/watertight_and_sample.py`
//! writes (`SampleMesh` L139-158, `sample_sdf` L62-137, saved L219-220), all `float16`:
//!
//! - `<stem>_surface.npz`: `random_surface` and `sharp_surface`, `[124928, 6]` (xyz + unit
//!   normal), what its DiT loader `hy3dshape/data/dit_asl.py` (`AlignedShapeLatentDataset.decode`
//!   L247-259) reads as `<item>/geo_data/<uid>_surface.npz`, drawing `pc_size` and
//!   `pc_sharpedge_size` rows without replacement;
//! - `<stem>_sdf.npz`: `vol_points` uniform in ±1.05, `random_near_points` (124928 at σ 0.005
//!   then 124928 at σ 0.05, truncated at ±0.25), `sharp_near_points` (six blocks at σ 0.001,
//!   0.003, 0.06, 0.01, 0.02, 0.04 of 20821 rows, the last 20823), each with its `*_label`
//!   `[K]` = −sdf: **positive inside**, as the code writes it (L125-127), although
//!   `tools/README.md` L74-77 says positive outside.
//!
//! The frame is the one its inference encodes meshes in (`hy3dshape/surface_loaders.py`
//! `normalize_mesh`, L23-44: the bounding box centred, its longest side onto ±0.9999). Its
//! public producer instead anchors meshes at the origin in [0, 0.99] (`normalize_to_unit_box`
//! L160-170) while drawing volume points in the centred ±1.05: we follow the inference frame,
//! which the released VAE decodes (docs/FORMAT.md, "Exports"). A mesh without a sharp edge is
//! left out, as its producer leaves it: `sharp_sample_pointcloud` (L29-59) indexes the empty
//! list of sharp edges and raises, so no file is written. Its DiT loader also reads 24
//! RGBA renders in `<item>/render_cond/` (`000.png` … `023.png`, composited on white): a job
//! with `[renders]` gets them there, with a `transforms.json` whose cameras are in this
//! export's frame ([`crate::renders`]).

use crate::arrays::{floats, placed, point_normal_rows, Width};
use crate::renders::SourceToExport;
use crate::select::{
    block_needs, block_rows, missing_needs, require_sharp, rows_in_cube, sharp_near_needs,
    sharp_near_rows, surface_and_sharp_needs, Need,
};
use crate::spec::{no_listing, takes_any_job, PresetSpec, Reads, Spec, Views};
use crate::Frame;
use crate::{npz::Array, npz_file, Item, ItemExport, Placement, Result};
use sparcubes::samples::SampleParams;

/// `--help` line.
pub const ABOUT: &str =
    "Hunyuan3D-2.1: <item>/geo_data/<item>_surface.npz and _sdf.npz (f16, label > 0 inside), and with [renders] <item>/render_cond/000.png …; checked against hy3dshape/data/dit_asl.py AlignedShapeLatentDataset";

/// Hunyuan3D-2.1 as the export, `--for` and `--help` know it.
pub const SPEC: Spec = Spec {
    name: "hunyuan3d-2.1",
    title: "Hunyuan3D-2.1",
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
    listing: no_listing,
};

/// Rows of `random_surface` and `sharp_surface` (`499712 // 4`, L143).
const SURFACE_ROWS: usize = 124_928;
/// The two halves of `random_near_points`, σ 0.005 and 0.05 (L66-75).
const NEAR_BLOCKS: [(f64, usize); 2] = [(0.005, SURFACE_ROWS), (0.05, SURFACE_ROWS)];
/// Rows of each sharp-near block but the last (`S // 6`); the last takes the rest.
const SHARP_NEAR_BLOCK: usize = SURFACE_ROWS / 6;
/// The six blocks of `sharp_near_points`, in order (L77-85).
const SHARP_NEAR_BLOCKS: [(f64, usize); 6] = [
    (0.001, SHARP_NEAR_BLOCK),
    (0.003, SHARP_NEAR_BLOCK),
    (0.06, SHARP_NEAR_BLOCK),
    (0.01, SHARP_NEAR_BLOCK),
    (0.02, SHARP_NEAR_BLOCK),
    (0.04, SURFACE_ROWS - 5 * SHARP_NEAR_BLOCK),
];
/// Rows of `vol_points` (`2·S`), uniform in ±[`VOLUME_BOUND`] (L63-64).
const VOLUME_ROWS: usize = 2 * SURFACE_ROWS;
/// Half side of the volume cube.
const VOLUME_BOUND: f64 = 1.05;
/// Half extent of the longest side in its frame (`normalize_mesh(scale=0.9999)`).
pub const HALF_EXTENT: f64 = 0.9999;

/// The `[samples]` counts it needs.
pub fn missing(samples: Option<&SampleParams>) -> Vec<String> {
    missing_needs(samples, |p| {
        let mut needs = surface_and_sharp_needs(p, SURFACE_ROWS);
        needs.push(Need::rows("volume", p.volume, VOLUME_ROWS));
        needs.extend(block_needs("near", p.near, &p.near_sigmas, &NEAR_BLOCKS));
        needs.extend(sharp_near_needs(p, &SHARP_NEAR_BLOCKS));
        needs
    })
}

/// The item's two files under `<stem>/geo_data/`.
pub fn files(item: &Item) -> Result<ItemExport> {
    let stored = item.stored_samples()?;
    let (s, p) = (stored.samples, stored.params);
    require_sharp(s, SURFACE_ROWS, "Hunyuan3D-2.1")?;
    let place = item.placement(HALF_EXTENT);
    let take = |v: &[[f32; 3]], n: usize| v[..n.min(v.len())].to_vec();
    let mut surface = crate::identity_arrays(item);
    surface.extend([
        surface_rows(
            "random_surface",
            &take(&s.surface_points, SURFACE_ROWS),
            &take(&s.surface_normals, SURFACE_ROWS),
            &place,
        ),
        surface_rows(
            "sharp_surface",
            &take(&s.sharp_points, SURFACE_ROWS),
            &take(&s.sharp_normals, SURFACE_ROWS),
            &place,
        ),
    ]);
    let near = block_rows(s.near_points.len(), &p.near_sigmas, &NEAR_BLOCKS, "near")?;
    let sharp_near = sharp_near_rows(s, p, &SHARP_NEAR_BLOCKS)?;
    let cube = item.consumer_cube(HALF_EXTENT);
    let volume = rows_in_cube(&s.volume_points, &cube, VOLUME_BOUND, VOLUME_ROWS);
    let labelled = |points: &str, label: &str, pts: &[[f32; 3]], sdf: &[f32], rows: &[usize]| {
        let chosen: Vec<[f32; 3]> = rows.iter().map(|&i| pts[i]).collect();
        let labels: Vec<f64> = rows.iter().map(|&i| -place.distance(sdf[i])).collect();
        [
            floats(
                points,
                vec![rows.len(), 3],
                &placed(&chosen, &place),
                Width::F16,
            ),
            floats(label, vec![rows.len()], &labels, Width::F16),
        ]
    };
    let mut sdf: Vec<Array> = Vec::new();
    sdf.extend(labelled(
        "vol_points",
        "vol_label",
        &s.volume_points,
        &s.volume_sdf,
        &volume,
    ));
    sdf.extend(labelled(
        "random_near_points",
        "random_near_label",
        &s.near_points,
        &s.near_sdf,
        &near,
    ));
    sdf.extend(labelled(
        "sharp_near_points",
        "sharp_near_label",
        &s.sharp_near_points,
        &s.sharp_near_sdf,
        &sharp_near,
    ));
    let dir = format!("{0}/geo_data/{0}", item.stem);
    let mut files = vec![
        npz_file(format!("{dir}_surface.npz"), &surface)?,
        npz_file(format!("{dir}_sdf.npz"), &sdf)?,
    ];
    let mut note = None;
    if let Some(r) = &item.renders {
        let dir = std::path::Path::new(item.stem).join("render_cond");
        let to_export = SourceToExport::through(&place, &item.cubes.normalization);
        files.extend(crate::renders::files(
            r,
            &dir,
            to_export,
            &crate::renders::three_digits,
        )?);
        note = (r.pngs.len() < RENDER_VIEWS).then_some(FEW_VIEWS);
    }
    Ok(ItemExport {
        files,
        note,
        ..Default::default()
    })
}

/// Views its DiT loader reads of each item: `render_cond/000.png` … `023.png`
/// (`AlignedShapeLatentDataset.decode`, L247-249).
pub const RENDER_VIEWS: usize = 24;

/// Hunyuan3D-2.1's condition views: TRELLIS's cameras, 24 of 512² (`hy3dshape/tools/render/
/// render.py` `init_render(resolution=512)` with TRELLIS's `sphere_hammersley_sequence`).
pub const RENDERS: crate::spec::RenderRecipe = crate::spec::RenderRecipe {
    recipe: "trellis",
    views: RENDER_VIEWS as u32,
    size: 512,
};

/// The note of an item with fewer views than its loader reads.
const FEW_VIEWS: &str = "fewer than the 24 condition views Hunyuan3D-2.1's loader reads (render_cond/000.png … 023.png): render them with [renders] views = 24";

/// `[n, 6]` f16 rows of points and normals.
fn surface_rows(name: &str, points: &[[f32; 3]], normals: &[[f32; 3]], place: &Placement) -> Array {
    floats(
        name,
        vec![points.len(), 6],
        &point_normal_rows(points, normals, place),
        Width::F16,
    )
}
