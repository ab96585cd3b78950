//! TRELLIS.2's flexible dual grid as its `FlexiDualGridDataset`
//! (`trellis2/datasets/flexi_dual_grid.py` of microsoft/TRELLIS.2) reads it, computed from the
//! stored grid's dual vertices ([`sparcubes::products::dual_vertices`]) as O-Voxel makes them
//! (`o-voxel/src/convert/flexible_dual_grid.cpp` and `data_toolkit/dual_grid.py`):
//!
//! - the voxels are the active cells (every cell with a crossed edge; TRELLIS.2 activates the
//!   four voxels around each crossed grid line, the same set);
//! - the dual vertex minimises a quadric error inside the voxel: the squared distances to the
//!   planes of the voxel's triangles plus [`REGULARIZATION`] × (number of crossings) × the
//!   squared distance to the mean of the crossing points on the voxel's edges (TRELLIS.2's
//!   face term with weight 1 and regularisation 1e-2), minimised over the closed voxel;
//! - it is stored as `floor(255 · (v − voxel))` per axis, 3 × `u8` (TRELLIS.2 clamps to
//!   [0, 1], scales by 255 and casts to `uint8`, [`quantize`]);
//! - `intersected` bit `a` (1, 2, 4 for x, y, z) says whether the surface crosses the voxel's
//!   grid edge along axis `a` at its upper corner in the other two axes (the edge whose four
//!   voxels TRELLIS.2 joins into a quad): for x the edge (0,1,1)–(1,1,1), for y (1,0,1)–(1,1,1),
//!   for z (1,1,0)–(1,1,1), i.e. a sign change of φ between those corners.
//!
//! The files:
//!
//! - `dual_grid_<N>/<key>.vxz`: o_voxel's container ([`crate::vxz`]) of the active voxels with
//!   `vertices` (3 × `u8`, the dual vertex inside its voxel, `floor(255·local)`) and
//!   `intersected` (1 × `u8`, bits 1/2/4 for x/y/z), what `data_toolkit/dual_grid.py`
//!   L58-77 writes and `read_dual_grid` (flexi_dual_grid.py L128-139) reads;
//! - `mesh_dumps/<key>.pickle`: `{'objects': [{'vertices': f32 (V, 3), 'faces': i32 (F, 3)}]}`
//!   (the layout of `data_toolkit/blender_script/dump_mesh.py` L192-230), the watertight mesh
//!   extracted from the item's cubes, which `read_mesh` (L106-126) loads;
//! - `pbr_voxels_<N>/<key>.vxz`: the item's appearance on the same voxels, for TRELLIS.2's
//!   texture VAE ([`pbr`]), when the job samples it (`[attributes]`);
//! - `renders_cond/<key>/{000..}.png` and `transforms.json`: the item's condition views, when
//!   the job renders them (`[renders]`), with `renders_cond/metadata.csv` (`cond_rendered`)
//!   and `data_dir.json`'s `render_cond`, as `data_toolkit/render_cond.py` writes them and
//!   `ImageConditionedMixin` (`trellis2/datasets/components.py`) reads them; the cameras in the
//!   mesh dump's frame ([`crate::renders`]);
//! - the `metadata.csv` of each folder of `data_dir.json` (`components.py`
//!   `StandardDatasetBase.__init__` L21-56 reads one per listed folder), with the columns
//!   `filter_metadata` (L92-104) asks for, and `data_dir.json` itself ([`listing`]).
//!
//! `<key>` is the item's source sha256 (TRELLIS.2 names files by the asset's sha256): the
//! manifest's, else the one its row recorded of the bytes it converted (a manifest of ids
//! alone), never the export stem, which is no sha256.
//!
//! Frame: TRELLIS.2's grid spans the aabb [−0.5, 0.5]³ at resolution G (`dual_grid.py`
//! L58-66), and its dataset centres every mesh dump's box and rescales its longest side to
//! 0.99999 of it (`read_mesh`, as `dual_grid.py` L36-56). A job made for TRELLIS.2 converts on
//! a grid 6 cells larger (the converter keeps 3 free cells per side) and the export cuts the
//! free cells off ([`Trellis2Grid`]): `resolution = G + 6` and `output_span = 0.99999·G/(G + 6)`
//! ([`job_for_grid`], what `--for trellis2@G` sets), with which the conversion frames the
//! *output's* box where `read_mesh` puts it (`sparcubes::stages::frame`); the export writes the
//! dump so that `read_mesh`'s centre is 0 and its scale 1 (`framed_positions`), so the mesh
//! it returns is the dump bit for bit and the dual grid agrees with it (voxel `i` of the
//! export is cell `i + 3` of the job). A job made before with `object_span` = [`span_for`]
//! is still exported in this frame as it was (its dump moves by about [`ROOM_CELLS`] under
//! `read_mesh`). Any other job is refused in that frame and written on its own grid with
//! `--frame normalized`, where the object spans `params.span()` of it (at most `(N − 6)/N`):
//! the files overlay each other, but `read_mesh` enlarges the dump to 0.99999 and [`check`]
//! warns with the factor.
//! The mesh dump is written in the export's aabb frame (`(cell − offset) / G − 0.5`), so
//! `(coord + vertices/255)/G − 0.5` lies on it. The axes are the source's (TRELLIS.2's own
//! dumps are Blender's Z-up world).
//!
//! `intersected`: TRELLIS.2 sets a bit where a triangle of the mesh it converts crosses the
//! edge (`flexible_dual_grid.cpp` L148-156), we where φ changes sign along it; on our
//! watertight output, the mesh dump, the two are the same bits (marching cubes crosses exactly
//! the edges with a sign change), and with the framed output also on the mesh `read_mesh`
//! returns (measured in docs/FORMAT.md, "`intersected`" and the run through TRELLIS.2's own
//! datasets), which is what its SC-VAE learns to predict and renders against.
//!
//! Frames (`--frame`): `consumer` is TRELLIS.2's grid exactly and needs a job made for it
//! (`--for trellis2@G`, [`check`] refuses any other); `normalized` writes the job's own grid
//! as it is.

pub mod pbr;

use crate::pickle::{self, Value};
use crate::spec::{needs_no_samples, PresetSpec, Reads, Spec, Views};
use crate::spec::{GridPreset, Settings};
use crate::vxz::{self, Attr};
use crate::{Error, ExportFile, Frame, Item, ItemExport, JobCheck, Listed, Result};
use sparcubes::products::dual_vertices::dual_vertices;
use sparcubes::{Params, SparseCubes};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// `--help` line.
pub const ABOUT: &str =
    "TRELLIS.2's dual grid dataset: dual_grid_<G>/<sha256>.vxz, mesh_dumps/, metadata.csv, data_dir.json (exact for a job at G + 6, docs/FORMAT.md), with [attributes] pbr_voxels_<G>/<sha256>.vxz on the same voxels, and with [renders] renders_cond/<sha256>/ (views and transforms.json); checked against trellis2/datasets/flexi_dual_grid.py FlexiDualGridDataset and sparse_voxel_pbr.py SparseVoxelPbrDataset";

/// TRELLIS.2 as the export, `--for` and `--help` know it.
pub const SPEC: Spec = Spec {
    name: "trellis2",
    title: "TRELLIS.2",
    about: ABOUT,
    frames: &[Frame::Consumer, Frame::Normalized],
    reads: Reads {
        samples: false,
        attributes: true,
    },
    preset: Some(PresetSpec {
        help: "TRELLIS.2's grid of G exactly",
        samples: false,
        renders: Some(RENDERS),
        grid: Some(GridPreset {
            form: "@G",
            required: true,
            accept: accept_grid,
            params: preset_params,
            misfit: preset_misfit,
        }),
    }),
    missing: needs_no_samples,
    check,
    files,
    views: Views::Own,
    listing,
};

/// The share of the grid TRELLIS.2 scales a mesh's longest side to (`dual_grid.py` L36-56,
/// `flexi_dual_grid.py` `read_mesh`).
pub const OBJECT_SPAN: f64 = 0.99999;

/// The name of the dataset in `data_dir.json`.
pub const DATASET: &str = "sparc3d";

/// Cells a TRELLIS.2-framed job keeps free on each side, cut off by the export.
pub const FREE_CELLS: u32 = 3;

/// Room left between the object's box and each side of TRELLIS.2's grid, in voxels: an open
/// surface becomes a shell reaching 0.9 voxel beyond it (`t` of docs/ALGORITHM.md §5), and
/// the normalization shifts the object by up to 0.037 voxel per axis
/// (`sparcubes::grid::normalization::GRID_OFFSET`) so that faces never lie on grid planes; a surface
/// past TRELLIS.2's last grid plane would need a voxel outside its grid.
pub const ROOM_CELLS: f64 = 1.0;

/// Largest gap, in cells, between a job's object size and the one [`span_for`] gives for the
/// job to count as converted in TRELLIS.2's frame (a span written with 7 digits is within
/// 1e-4 cells).
const SPAN_TOLERANCE_CELLS: f64 = 1e-4;

/// TRELLIS.2's grid within a job's grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Trellis2Grid {
    /// Voxels per axis of the exported grid (`dual_grid_<size>`).
    pub size: u32,
    /// The job's cell at the export's voxel 0, per axis.
    pub offset: u32,
    /// Whether the job framed its output's box as `read_mesh` places it
    /// (`params.output_span`, [`output_span_for`]): the mesh dump is then written so that
    /// `read_mesh` moves none of it ([`framed_positions`]).
    pub framed: bool,
}

impl Trellis2Grid {
    /// The grid a job at `resolution` exports: TRELLIS.2's own of `resolution − 6` when its
    /// output's box spans `output_span` = [`output_span_for`] of it (a job made with
    /// `--for trellis2@G`), or, for a job without an output span, when its object spans
    /// `span` = [`span_for`] (the preset's jobs before the output was framed); else the job's.
    pub fn of(resolution: u32, span: f64, output_span: Option<f64>) -> Self {
        let exact = |size: u32| match output_span {
            Some(s) => near(s, output_span_for(size), resolution),
            None => near(span, span_for(size), resolution),
        };
        match resolution.checked_sub(2 * FREE_CELLS) {
            Some(size) if size > 0 && exact(size) => Self {
                size,
                offset: FREE_CELLS,
                framed: output_span.is_some(),
            },
            _ => Self::whole(resolution),
        }
    }

    /// The job's own grid of `resolution`, as it is (`--frame normalized`).
    pub fn whole(resolution: u32) -> Self {
        Self {
            size: resolution,
            offset: 0,
            framed: false,
        }
    }

    /// Whether the object sits in this grid as TRELLIS.2's dataset places its mesh.
    pub fn is_exact(&self) -> bool {
        self.offset == FREE_CELLS
    }
}

/// Whether two spans of a grid of `resolution` differ by at most [`SPAN_TOLERANCE_CELLS`].
fn near(span: f64, wanted: f64, resolution: u32) -> bool {
    (span - wanted).abs() * resolution as f64 <= SPAN_TOLERANCE_CELLS
}

/// The `object_span` that `--for trellis2@G` set before the output was framed (a job made
/// so is still exported in TRELLIS.2's frame, as it was): the source's longest side 0.99999
/// of the grid less [`ROOM_CELLS`] at each end, so that `read_mesh`'s rescaling of a closed
/// object's dump moves each end of it by about [`ROOM_CELLS`] against the dual grid.
pub fn span_for(size: u32) -> f64 {
    (OBJECT_SPAN * size as f64 - 2.0 * ROOM_CELLS) / (size + 2 * FREE_CELLS) as f64
}

/// The `output_span` of a job at `size + 6` whose output TRELLIS.2's `read_mesh` reads where
/// it is: its box centred, its longest side 0.99999 of the grid of `size`
/// (`flexi_dual_grid.py` `read_mesh`; the conversion frames it, `sparcubes::stages::frame`).
pub fn output_span_for(size: u32) -> f64 {
    OBJECT_SPAN * size as f64 / (size + 2 * FREE_CELLS) as f64
}

/// The largest grid `--for trellis2@G` takes: its job converts at `G + 6`, at most the
/// largest resolution.
pub const MAX_GRID: u32 = sparcubes::params::MAX_RESOLUTION - 2 * FREE_CELLS;

/// The `(resolution, output_span)` of a job whose export is TRELLIS.2's grid of `size`
/// exactly: `size + 6` and [`output_span_for`] (what `--for trellis2@size` sets).
pub fn job_for_grid(size: u32) -> (u32, f64) {
    (size + 2 * FREE_CELLS, output_span_for(size))
}

/// `--for trellis2@G`'s grid: required, and at most [`MAX_GRID`].
fn accept_grid(text: &str, grid: Option<u32>) -> Result<()> {
    match grid {
        None => Err(Error::Invalid(format!(
            "--for {text}: name TRELLIS.2's grid, e.g. trellis2@256, trellis2@512 or \
             trellis2@1024 (the job converts at G + 6 and the export cuts the 3 free cells \
             of each side off)"
        ))),
        Some(g) if g > MAX_GRID => Err(Error::Invalid(format!(
            "--for {text}: TRELLIS.2's grid is at most {MAX_GRID} here (the job converts at \
             G + 6, and the largest resolution is {}); use trellis2@{MAX_GRID} or a smaller grid",
            sparcubes::params::MAX_RESOLUTION
        ))),
        Some(_) => Ok(()),
    }
}

/// What `--for trellis2@G` sets: the job of [`job_for_grid`] (nothing without a grid, which
/// [`accept_grid`] refuses).
fn preset_params(grid: Option<u32>) -> Settings {
    let Some(g) = grid else {
        return Settings::NONE;
    };
    let (resolution, span) = job_for_grid(g);
    Settings {
        resolution: Some(resolution),
        output_span: Some(span),
        ..Settings::NONE
    }
}

/// What a job made with `--for trellis2@grid` lacks for TRELLIS.2's frame when a config key
/// or flag changed its span but not its resolution: the preset's own grid, not one from the
/// job's resolution as [`check`] would advise (issue 64 item 10: `trellis2@48` with another
/// `object_span` was told to use `trellis2@54`); `None` when the resolution was changed too,
/// or nothing was.
pub fn preset_misfit(grid: u32, params: &Params) -> Option<String> {
    let (resolution, span) = job_for_grid(grid);
    let own = Trellis2Grid::of(resolution, params.span(), params.output_span);
    if params.resolution != resolution || own.is_exact() {
        return None;
    }
    let key = match params.output_span {
        Some(_) => "output_span",
        None => "object_span",
    };
    Some(format!(
        "params.{key} = {} replaces the preset's output_span = {span} (TRELLIS.2's grid of \
         {grid} exactly), so the export in TRELLIS.2's frame refuses this job: leave {key} out \
         of the config (the preset sets output_span), or export with --frame normalized to \
         write the job's own grid as it is",
        params.span()
    ))
}

/// In TRELLIS.2's frame (`Frame::Consumer`, the default): nothing for a job made for it
/// (`--for trellis2@G`), else the settings it lacks, naming the preset (refused, as
/// Direct3D-S2 refuses a job without its span). In the job's own frame (`Frame::Normalized`):
/// a warning that the dataset's rescaled mesh and the grid differ by `0.99999 / span`.
pub fn check(params: &Params, frame: Frame) -> JobCheck {
    let span = params.span();
    let n = params.resolution;
    let exact = Trellis2Grid::of(n, span, params.output_span).is_exact();
    let (resolution, exact_span) = job_for_grid(n);
    let rescaled = |size: u32| {
        let cells = (OBJECT_SPAN - span) * size as f64 / 2.0;
        format!(
            "TRELLIS.2's dataset rescales each mesh dump to span {OBJECT_SPAN} of the grid \
             (flexi_dual_grid.py read_mesh) while this job's objects span {span:.5} of its \
             grid of {n}: the mesh it reads is {:.2} % larger than the grid's surface \
             ({cells:.2} voxels at each side of the longest axis)",
            (OBJECT_SPAN / span - 1.0) * 100.0
        )
    };
    match frame {
        Frame::Consumer if exact => JobCheck::default(),
        Frame::Consumer => JobCheck {
            required: vec![format!(
                "params.resolution = {resolution} and params.output_span = {exact_span}, \
                 TRELLIS.2's grid of {n} exactly: make the job with --for trellis2@{n} \
                 (docs/FORMAT.md); {}; or export with --frame normalized to write the job's \
                 own grid as it is",
                rescaled(n)
            )],
            warnings: Vec::new(),
        },
        _ => JobCheck {
            required: Vec::new(),
            warnings: vec![format!(
                "--frame normalized writes the job's own grid of {n}: {}; the files as written \
                 overlay exactly (for TRELLIS.2's frame: --for trellis2@{n} and --frame \
                 consumer)",
                rescaled(n)
            )],
        },
    }
}

/// The item's `.vxz` and mesh dump, and its columns for the listings.
pub fn files(item: &Item) -> Result<ItemExport> {
    let resolution = item.cubes.resolution;
    let grid = match item.frame {
        Frame::Normalized => Trellis2Grid::whole(resolution),
        _ => Trellis2Grid::of(resolution, item.object_span, item.output_span),
    };
    if item.frame == Frame::Consumer && !grid.is_exact() {
        return Err(Error::Invalid(format!(
            "the job's grid of {resolution} is not in TRELLIS.2's frame (see `check`)"
        )));
    }
    let n = grid.size;
    let key = item.source_key.ok_or_else(|| {
        Error::Missing("no sha256 of its source recorded (TRELLIS.2 names files by it)".into())
    })?;
    let g = dual_grid(item.cubes);
    let coords = voxels_in(&g.voxels, grid)?;
    let vertices: Vec<u8> = g.quantized.iter().flatten().copied().collect();
    let attrs = [
        Attr {
            name: "vertices",
            channels: 3,
            data: &vertices,
        },
        Attr {
            name: "intersected",
            channels: 1,
            data: &g.intersected,
        },
    ];
    let dual = vxz::vxz_bytes(&coords, &attrs, vxz::CHUNK_SIZE)?;
    let mesh = sparcubes::extract(item.cubes);
    let dump = mesh_dump(&mesh, grid)?;
    let mut listing = BTreeMap::from([
        ("sha256".to_string(), key.to_string()),
        ("dual_grid_size".to_string(), coords.len().to_string()),
        ("num_vertices".to_string(), mesh.positions.len().to_string()),
        ("num_faces".to_string(), mesh.triangles.len().to_string()),
    ]);
    // The dual grid file stays first: `listing` finds its folder there.
    let mut files = vec![
        ExportFile {
            path: PathBuf::from(format!("dual_grid_{n}")).join(format!("{key}.vxz")),
            bytes: dual,
        },
        ExportFile {
            path: PathBuf::from("mesh_dumps").join(format!("{key}.pickle")),
            bytes: dump,
        },
    ];
    if let Some(r) = &item.renders {
        let dir = PathBuf::from(RENDERS_DIR).join(key);
        files.extend(crate::renders::files(
            r,
            &dir,
            source_to_export(item.cubes, grid),
            &crate::renders::three_digits,
        )?);
        listing.insert(COND_RENDERED.to_string(), "True".to_string());
    }
    let note = match item.attributes {
        Some(a) => {
            files.push(pbr::file(&item.cubes.cells, a, &g.voxels, &coords, n, key)?);
            listing.insert(pbr::COUNT_COLUMN.to_string(), coords.len().to_string());
            None
        }
        None => Some(pbr::NO_ATTRIBUTES),
    };
    Ok(ItemExport {
        files,
        listing,
        note,
    })
}

/// The folder of the condition views, one folder per item named by its key, as TRELLIS.2's
/// `data_toolkit/render_cond.py` writes `renders_cond/<sha256>/` and `ImageConditionedMixin`
/// (`trellis2/datasets/components.py`) reads it through `data_dir.json`'s `render_cond`.
pub const RENDERS_DIR: &str = "renders_cond";

/// TRELLIS.2's condition views: 16 of 1024² with its own lights (`data_toolkit/render_cond.py`
/// `--num_cond_views` 16, `--cond_resolution` 1024).
pub const RENDERS: crate::spec::RenderRecipe = crate::spec::RenderRecipe {
    recipe: "trellis2",
    views: 16,
    size: 1024,
};

/// The listing column `ImageConditionedMixin.filter_metadata` keeps the items of.
const COND_RENDERED: &str = "cond_rendered";

/// Where a source point lands in the export's aabb frame of `grid` (the mesh dump's frame):
/// `(source_to_grid(p) − offset) / G − 0.5`.
fn source_to_export(cubes: &SparseCubes, grid: Trellis2Grid) -> crate::renders::SourceToExport {
    let n = cubes.resolution as f64;
    let g = grid.size as f64;
    let norm = &cubes.normalization;
    let a = norm.scale * n / g;
    let b = norm
        .center
        .map(|c| (0.5 - c * norm.scale) * n / g - grid.offset as f64 / g - 0.5);
    crate::renders::SourceToExport { a, b }
}

/// Weight of the pull towards the mean crossing point, per crossing (TRELLIS.2's
/// `regularization_weight=1e-2` in `data_toolkit/dual_grid.py`).
pub const REGULARIZATION: f64 = 1e-2;

/// TRELLIS.2's flexible dual grid of one item.
struct DualGrid {
    /// Active voxels (cells) by minimum corner, sorted.
    voxels: Vec<[u16; 3]>,
    /// Quantised dual vertices ([`quantize`]).
    quantized: Vec<[u8; 3]>,
    /// Intersected flags: bit 0 x, bit 1 y, bit 2 z (module docs).
    intersected: Vec<u8>,
}

/// The flexible dual grid of `cubes`, with TRELLIS.2's regularisation and quantisation.
fn dual_grid(cubes: &SparseCubes) -> DualGrid {
    let d = dual_vertices(cubes, REGULARIZATION);
    DualGrid {
        quantized: d.vertices.iter().map(|v| v.map(quantize)).collect(),
        voxels: d.cells,
        intersected: d.crossed,
    }
}

/// TRELLIS.2's quantisation of a local coordinate: clamp to [0, 1], scale by 255, truncate.
#[inline]
pub fn quantize(x: f32) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0) as u8
}

/// The job's voxels as indices of `grid`; refuses a voxel outside it (a surface in the
/// job's free cells, which TRELLIS.2's grid does not have).
fn voxels_in(voxels: &[[u16; 3]], grid: Trellis2Grid) -> Result<Vec<[u32; 3]>> {
    let shifted = |c: &[u16; 3]| -> Option<[u32; 3]> {
        let mut out = [0u32; 3];
        for (o, &v) in out.iter_mut().zip(c) {
            *o = u32::from(v)
                .checked_sub(grid.offset)
                .filter(|&i| i < grid.size)?;
        }
        Some(out)
    };
    voxels
        .iter()
        .map(|c| {
            shifted(c).ok_or_else(|| {
                Error::Invalid(format!(
                    "voxel {c:?} lies outside TRELLIS.2's grid of {} (cells {}..{} of the \
                     job's): the surface reaches into the free cells",
                    grid.size,
                    grid.offset,
                    grid.offset + grid.size
                ))
            })
        })
        .collect()
}

/// The pickle of `mesh` (the job's grid coordinates) in the aabb frame of `grid`; for a
/// framed job, as [`framed_positions`] writes it.
fn mesh_dump(mesh: &sparcubes::TriMesh, grid: Trellis2Grid) -> Result<Vec<u8>> {
    let scale = 1.0 / grid.size as f64;
    let offset = grid.offset as f64;
    let mut positions: Vec<[f32; 3]> = mesh
        .positions
        .iter()
        .map(|p| p.map(|v| ((v as f64 - offset) * scale - 0.5) as f32))
        .collect();
    if grid.framed {
        framed_positions(&mut positions, grid.size)?;
    }
    let positions: Vec<f64> = positions.iter().flatten().map(|&v| v as f64).collect();
    let faces: Vec<u8> = mesh
        .triangles
        .iter()
        .flatten()
        .flat_map(|&i| (i as i32).to_le_bytes())
        .collect();
    let object = Value::Dict(vec![
        ("vertices".into(), pickle::f32_rows(&positions, 3)),
        (
            "faces".into(),
            Value::Array {
                descr: "<i4",
                shape: vec![mesh.triangles.len(), 3],
                data: faces,
            },
        ),
    ]);
    Ok(pickle::dumps(&Value::Dict(vec![(
        "objects".into(),
        Value::List(vec![object]),
    )])))
}

/// The longest side of the dump's box, in `f32` as `read_mesh` computes it: 0.99999, whose
/// `0.99999 / side` is exactly 1 in `f32` (torch computes it as `side.reciprocal() · 0.99999`,
/// and `f32(1/x)·x` rounds to 1 for this `x`; checked in the unit tests).
const FRAMED_SIDE: f32 = OBJECT_SPAN as f32;

/// Largest move, in voxels, [`framed_positions`] makes: the conversion put the output's ends
/// within `sparcubes::stages::frame::SNAP_TOLERANCE` of their targets, and the `f32` of the
/// dump rounds them by 1e-5 voxel at the most.
const FRAMED_TOLERANCE: f64 = 2e-4;

/// Puts the dump's box where `read_mesh` (`flexi_dual_grid.py` L106-126) would move it, so
/// that it moves nothing: on each axis the box symmetric about 0 in `f32` (its centre
/// `(min + max) / 2` exactly 0), the longest side exactly [`FRAMED_SIDE`] (its scale exactly
/// 1). The framed conversion put the ends there to [`FRAMED_TOLERANCE`]; they are rounded onto
/// it here (the points beyond it moved back, the outermost one out), each a move along its
/// own grid edge of under 1e-4 voxel. An output not so framed is refused.
fn framed_positions(positions: &mut [[f32; 3]], size: u32) -> Result<()> {
    let tolerance = (FRAMED_TOLERANCE / size as f64) as f32;
    let (lo, hi) = f32_bounds(positions);
    let longest = (0..3).fold(0, |m, a| if hi[a] - lo[a] > hi[m] - lo[m] { a } else { m });
    for a in 0..3 {
        let end = match a == longest {
            true => FRAMED_SIDE / 2.0,
            false => (-lo[a]).max(hi[a]).min(FRAMED_SIDE / 2.0),
        };
        let off = (lo[a] + end).abs().max((hi[a] - end).abs());
        if off.is_nan() || off > tolerance {
            return Err(Error::Invalid(format!(
                "the output's box on axis {a} spans [{}, {}], {:.2e} voxel from where TRELLIS.2's \
                 read_mesh puts it (±{end}): the conversion could not frame it (its ends in \
                 other cells than their targets'); export with --frame normalized",
                lo[a],
                hi[a],
                off as f64 * size as f64
            )));
        }
        round_ends(positions, a, end);
    }
    Ok(())
}

/// The box of `positions` in `f32`.
fn f32_bounds(positions: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in positions {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    (lo, hi)
}

/// Clamps axis `a` of `positions` to `[−end, end]` and puts the lowest and highest on them.
fn round_ends(positions: &mut [[f32; 3]], a: usize, end: f32) {
    for p in positions.iter_mut() {
        p[a] = p[a].clamp(-end, end);
    }
    let order = |i: &usize, j: &usize| positions[*i][a].total_cmp(&positions[*j][a]);
    let lowest = (0..positions.len()).min_by(order);
    let highest = (0..positions.len()).max_by(order);
    for (i, v) in [(lowest, -end), (highest, end)] {
        if let Some(i) = i {
            positions[i][a] = v;
        }
    }
}

/// The folders' `metadata.csv` (base, `mesh_dumps`, `dual_grid_<N>`, `asset_stats`, and
/// `pbr_voxels_<N>` when any item has PBR voxels, [`pbr::listing`]) and `data_dir.json` naming
/// them under `root`, the JSON object `--data_dir` takes (README.md
/// L228-238). `aesthetic_score` is not known here: add the column to `metadata.csv` or pass
/// `min_aesthetic_score: null` to the dataset. Refuses two items with the same key.
pub fn listing(items: &[Listed], root: &Path) -> Result<Vec<ExportFile>> {
    let Some(grid_dir) = items
        .first()
        .and_then(|i| i.files.first())
        .and_then(|f| f.parent())
        .map(Path::to_path_buf)
    else {
        return Ok(Vec::new());
    };
    refuse_repeated_keys(items)?;
    let col = |i: &Listed, k: &str| i.columns.get(k).cloned().unwrap_or_default();
    let table = |dir: &Path, header: &str, row: &dyn Fn(&Listed) -> Vec<String>| ExportFile {
        path: dir.join("metadata.csv"),
        bytes: csv(header, items.iter().map(row)).into_bytes(),
    };
    let mut folders = serde_json::json!({
        "base": root,
        "mesh_dump": root.join("mesh_dumps"),
        "dual_grid": root.join(&grid_dir),
        "asset_stats": root.join("asset_stats"),
    });
    let pbr = pbr::listing(items);
    if let Some((dir, _)) = &pbr {
        folders[pbr::DATA_DIR_KEY] = serde_json::json!(root.join(dir));
    }
    let rendered: Vec<&Listed> = items
        .iter()
        .filter(|i| i.columns.contains_key(COND_RENDERED))
        .collect();
    if !rendered.is_empty() {
        folders["render_cond"] = serde_json::json!(root.join(RENDERS_DIR));
    }
    let data_dir = serde_json::to_vec_pretty(&serde_json::json!({ DATASET: folders }))
        .map_err(|e| Error::Invalid(format!("writing data_dir.json: {e}")))?;
    let mut files = vec![
        provenance_table(items, &col),
        table(Path::new("mesh_dumps"), "sha256,mesh_dumped", &|i| {
            vec![col(i, "sha256"), "True".into()]
        }),
        table(
            &grid_dir,
            "sha256,dual_grid_converted,dual_grid_size",
            &|i| vec![col(i, "sha256"), "True".into(), col(i, "dual_grid_size")],
        ),
        table(
            Path::new("asset_stats"),
            "sha256,num_vertices,num_faces",
            &|i| {
                vec![
                    col(i, "sha256"),
                    col(i, "num_vertices"),
                    col(i, "num_faces"),
                ]
            },
        ),
    ];
    files.extend(pbr.map(|(_, table)| table));
    if !rendered.is_empty() {
        files.push(ExportFile {
            path: Path::new(RENDERS_DIR).join("metadata.csv"),
            bytes: csv(
                "sha256,cond_rendered",
                rendered
                    .iter()
                    .map(|i| vec![col(i, "sha256"), "True".into()]),
            )
            .into_bytes(),
        });
    }
    files.push(ExportFile {
        path: "data_dir.json".into(),
        bytes: data_dir,
    });
    Ok(files)
}

/// Two items of one source (the same sha256) would share their files.
fn refuse_repeated_keys(items: &[Listed]) -> Result<()> {
    let mut seen: BTreeMap<&str, &str> = BTreeMap::new();
    for i in items {
        let key = i.columns.get("sha256").map_or("", String::as_str);
        if let Some(first) = seen.insert(key, &i.id) {
            return Err(Error::Invalid(format!(
                "items {first:?} and {:?} have the same source sha256 {key}: TRELLIS.2 names \
                 files by it; export one of them (--ids)",
                i.id
            )));
        }
    }
    Ok(())
}

/// A CSV text: `header`, then one line per row, fields quoted where they need it.
fn csv(header: &str, rows: impl Iterator<Item = Vec<String>>) -> String {
    let mut out = format!("{header}\n");
    for row in rows {
        let fields: Vec<String> = row.iter().map(|f| csv_field(f)).collect();
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    out
}

/// The root `metadata.csv`: `sha256,id`, then the items' provenance columns as
/// `manifest.<name>` (TRELLIS.2 reads the columns it knows by name; the others ride along).
fn provenance_table(items: &[Listed], col: &dyn Fn(&Listed, &str) -> String) -> ExportFile {
    let names: std::collections::BTreeSet<&String> =
        items.iter().flat_map(|i| i.provenance.keys()).collect();
    let mut header = "sha256,id".to_string();
    for n in &names {
        header.push_str(&format!(",{}", csv_field(&format!("manifest.{n}"))));
    }
    let row = |i: &Listed| {
        let mut fields = vec![col(i, "sha256"), i.id.clone()];
        fields.extend(
            names
                .iter()
                .map(|n| i.provenance.get(*n).cloned().unwrap_or_default()),
        );
        fields
    };
    ExportFile {
        path: PathBuf::from("metadata.csv"),
        bytes: csv(&header, items.iter().map(row)).into_bytes(),
    }
}

/// A field as CSV writes it: quoted, with quotes doubled, when it holds `,`, `"` or a line
/// break.
fn csv_field(f: &str) -> String {
    if f.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", f.replace('"', "\"\""))
    } else {
        f.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn listed(id: &str, sha: &str) -> Listed {
        Listed {
            id: id.into(),
            stem: id.into(),
            files: vec![PathBuf::from("dual_grid_64").join(format!("{sha}.vxz"))],
            columns: BTreeMap::from([
                ("sha256".to_string(), sha.to_string()),
                ("dual_grid_size".to_string(), "7".to_string()),
            ]),
            provenance: BTreeMap::new(),
        }
    }

    #[test]
    fn a_job_six_cells_larger_at_trellis2_size_exports_its_grid() {
        for size in [48, 256, 512, 1024] {
            let (resolution, output) = job_for_grid(size);
            let framed = Trellis2Grid::of(resolution, output, Some(output));
            let grid = |offset, framed| Trellis2Grid {
                size,
                offset,
                framed,
            };
            assert_eq!(framed, grid(3, true));
            assert!(framed.is_exact());
            // A job of the preset before the output was framed keeps its frame.
            let earlier = Trellis2Grid::of(size + 6, span_for(size), None);
            assert_eq!(earlier, grid(3, false));
            // Seven digits of the span are enough; a default job keeps its own grid.
            let rounded = (output * 1e7).round() / 1e7;
            assert!(Trellis2Grid::of(resolution, rounded, Some(rounded)).is_exact());
            let default = Trellis2Grid::of(size, (size - 6) as f64 / size as f64, None);
            assert_eq!(default, grid(0, false));
            let off = output * 0.999;
            assert!(!Trellis2Grid::of(resolution, off, Some(off)).is_exact());
            // The old span as an output span is no frame, nor the new one as a source's.
            assert!(!Trellis2Grid::of(resolution, span_for(size), Some(span_for(size))).is_exact());
            assert!(!Trellis2Grid::of(resolution, output, None).is_exact());
        }
        let shift = sparcubes::normalize::GRID_OFFSET
            .iter()
            .fold(0.0f64, |m, &v| m.max(v));
        assert!(ROOM_CELLS > 0.9 + shift);
        let mut params = Params {
            resolution: 518,
            output_span: Some(output_span_for(512)),
            ..Params::default()
        };
        assert!(params.validate().is_ok());
        assert_eq!(check(&params, Frame::Consumer), JobCheck::default());
        params.output_span = None;
        // Not in its frame: refused in TRELLIS.2's, naming the preset; written with a warning
        // in the job's own.
        let refused = check(&params, Frame::Consumer).required.join(" ");
        assert!(refused.contains("--for trellis2@518"), "{refused}");
        assert!(refused.contains("params.resolution = 524"), "{refused}");
        let own = check(&params, Frame::Normalized);
        assert!(
            own.required.is_empty() && own.warnings[0].contains("1.17 %"),
            "{own:?}"
        );
    }

    /// `read_mesh`'s arithmetic in `f32`: the centre `(min + max) / 2` and the scale
    /// `0.99999 / side` as torch computes it (`side.reciprocal() · 0.99999`).
    fn read_mesh_frame(positions: &[[f32; 3]]) -> ([f32; 3], f32) {
        let (lo, hi) = f32_bounds(positions);
        let side = (0..3).map(|a| hi[a] - lo[a]).fold(0.0f32, f32::max);
        let centre = std::array::from_fn(|a| (lo[a] + hi[a]) / 2.0);
        (centre, (1.0f32 / side) * OBJECT_SPAN as f32)
    }

    #[test]
    fn a_framed_dump_is_where_read_mesh_puts_it() {
        assert_eq!((1.0f32 / FRAMED_SIDE) * OBJECT_SPAN as f32, 1.0);
        assert_eq!(OBJECT_SPAN as f32 / FRAMED_SIDE, 1.0);
        let size = 64;
        let voxel = 1.0 / size as f32;
        let h = FRAMED_SIDE / 2.0;
        // Ends a little off the targets (under the tolerance), one axis shorter.
        let mut positions = vec![
            [-h + 0.5e-4 * voxel, 0.1, -0.2],
            [
                h - 0.3e-4 * voxel,
                -0.3 - 0.2e-4 * voxel,
                0.2 + 1e-5 * voxel,
            ],
            [0.0, 0.3, 0.0],
        ];
        let before = positions.clone();
        assert!(framed_positions(&mut positions, size).is_ok());
        let (centre, scale) = read_mesh_frame(&positions);
        assert_eq!((centre, scale), ([0.0; 3], 1.0), "{positions:?}");
        let moved = before
            .iter()
            .zip(&positions)
            .flat_map(|(p, q)| (0..3).map(move |a| (p[a] - q[a]).abs()))
            .fold(0.0f32, f32::max);
        assert!(moved <= 1e-4 * voxel, "{moved}");
        // An end a voxel off is refused, naming the axis.
        let mut far = vec![[-h, -0.3, 0.0], [h, 0.3 - voxel, 0.0]];
        let refused = framed_positions(&mut far, size).map_err(|e| e.to_string());
        assert!(
            matches!(&refused, Err(m) if m.contains("axis 1")),
            "{refused:?}"
        );
    }

    #[test]
    fn voxels_move_into_the_export_grid_or_are_refused() {
        let grid = Trellis2Grid {
            size: 10,
            offset: 3,
            framed: false,
        };
        let moved = voxels_in(&[[3, 4, 12]], grid).unwrap_or_default();
        assert_eq!(moved, vec![[0, 1, 9]]);
        for outside in [[2, 4, 5], [3, 4, 13]] {
            assert!(voxels_in(&[outside], grid).is_err(), "{outside:?}");
        }
    }

    #[test]
    fn every_listed_folder_gets_a_metadata_file() {
        let files = listing(
            &[listed("a,\"b\"", "f00"), listed("c", "ba5")],
            Path::new("/x"),
        )
        .unwrap_or_default();
        let names: Vec<String> = files
            .iter()
            .map(|f| f.path.to_string_lossy().into_owned())
            .collect();
        assert_eq!(
            names,
            [
                "metadata.csv",
                "mesh_dumps/metadata.csv",
                "dual_grid_64/metadata.csv",
                "asset_stats/metadata.csv",
                "data_dir.json"
            ]
        );
        let base = String::from_utf8_lossy(&files[0].bytes).into_owned();
        assert_eq!(base, "sha256,id\nf00,\"a,\"\"b\"\"\"\nba5,c\n");
        let grid = String::from_utf8_lossy(&files[2].bytes).into_owned();
        assert_eq!(
            grid,
            "sha256,dual_grid_converted,dual_grid_size\nf00,True,7\nba5,True,7\n"
        );
        assert!(listing(&[listed("a", "f00"), listed("b", "f00")], Path::new("/x")).is_err());
    }

    #[test]
    fn the_root_metadata_carries_the_provenance_columns() {
        let mut a = listed("a", "f00");
        a.provenance = BTreeMap::from([
            ("license".to_string(), "cc0".to_string()),
            ("name".to_string(), "x, y".to_string()),
        ]);
        let files = listing(&[a, listed("b", "ba5")], Path::new("/x")).unwrap_or_default();
        let base = files
            .first()
            .map(|f| String::from_utf8_lossy(&f.bytes).into_owned())
            .unwrap_or_default();
        assert_eq!(
            base,
            "sha256,id,manifest.license,manifest.name\nf00,a,cc0,\"x, y\"\nba5,b,,\n"
        );
    }
}
