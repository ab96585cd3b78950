//! The on-disk layouts other codebases train on, one module per consumer, each written from
//! what [`sparcubes`] computes for one item (its sparse cubes, its samples) and nothing else:
//! the geometry stays in `sparcubes`, which knows nothing of who reads it; here live each
//! consumer's recipe (which of our arrays, in which frame, with which sign and index range),
//! its folder layout and file names, and its listing files; and the writing of an export
//! folder ([`export`]: staged beside its destination, recorded, moved into place).
//!
//! A consumer module describes itself in one `SPEC` ([`spec::Spec`]): its name, `--help`
//! line, frames, what it reads, its preset, and its functions: `files` (one item's files),
//! `listing` (the files that list the items), `missing` (the `[samples]` keys a job lacks for
//! it), `check` (the job settings its frame needs). [`Consumer`] is a handle on one, and
//! [`Consumer::ALL`] the table of them; adding a consumer is one file and one entry there
//! (ARCHITECTURE.md, "Adding a consumer"). docs/FORMAT.md ("Exports") has the table of
//! consumers, files and the loaders each was checked against.

#![deny(missing_docs)]

mod arrays;
pub mod consumer;
pub mod cubvh;
pub mod direct3d_s2;
pub mod dora;
mod error;
pub mod export;
pub mod frame;
pub mod hunyuan3d;
pub mod npz;
pub mod pickle;
pub mod preset;
pub mod renders;
mod select;
pub mod spec;
pub mod step1x3d;
pub mod trellis2;
pub mod triposg;
pub mod vecset;
pub mod vxz;

pub use consumer::Consumer;
pub use error::{Error, Result};
pub use frame::{Frame, Placement};

use sparcubes::attributes::CellAttributes;
use sparcubes::cubes::SparseCubes;
use sparcubes::samples::{SampleParams, Samples};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// One item to export: what the job stored for it.
#[derive(Debug, Clone, Copy)]
pub struct Item<'a> {
    /// The item's id.
    pub id: &'a str,
    /// Its row in the frozen manifest.
    pub item_index: u64,
    /// Its file stem in the export, unique within the job (`<index>-<id>`, shortened).
    pub stem: &'a str,
    /// What names its source (TRELLIS.2 names files by it): the sha256 of its source file
    /// (the manifest's, else the one its row recorded of the bytes converted), or its id when
    /// that id also covers the files the mesh names (`<sha256>-<16 hex>`: colour variants of
    /// one mesh file are two items, each with its own files).
    pub source_key: Option<&'a str>,
    /// Its sparse cubes (with the job's normalization).
    pub cubes: &'a SparseCubes,
    /// Its samples, when the job draws them.
    pub samples: Option<StoredSamples<'a>>,
    /// Its appearance on `cubes.cells` (one row per cell), when the job samples it
    /// (`[attributes]`) and the consumer reads it ([`Consumer::reads_attributes`]).
    pub attributes: Option<&'a CellAttributes>,
    /// Its condition views, when the job renders them (`[renders]`).
    pub renders: Option<renders::StoredRenders<'a>>,
    /// The fraction of the grid's side the object's longest side spans
    /// (`sparcubes::Params::span`: `params.object_span`, else what `params.margin_cells`
    /// leaves).
    pub object_span: f64,
    /// The fraction of the grid's side the *output's* box spans, centred, when the job framed
    /// it (`sparcubes::Params::output_span`, what `--for trellis2@G` sets).
    pub output_span: Option<f64>,
    /// The frame the files are written in (one of [`Consumer::frames`]).
    pub frame: Frame,
}

impl<'a> Item<'a> {
    /// The placement of points in this item's frame: the consumer's cube (its bounding box
    /// centred, its longest side on ±`half_extent`), the normalized frame or the source's.
    pub fn placement(&self, half_extent: f64) -> Placement {
        match self.frame {
            Frame::Consumer => self.consumer_cube(half_extent),
            Frame::Normalized => Placement::IDENTITY,
            Frame::Source => Placement::to_source(&self.cubes.normalization),
        }
    }

    /// Its samples, or an error when the job stored none.
    pub fn stored_samples(&self) -> Result<StoredSamples<'a>> {
        self.samples.ok_or_else(|| {
            Error::Missing(
                "no sample columns (config key samples.enabled was off when it converted)".into(),
            )
        })
    }

    /// The placement into the consumer's cube, whatever the frame written: a consumer's rule
    /// such as "volume points in ±1.05" picks the same rows in every frame.
    pub fn consumer_cube(&self, half_extent: f64) -> Placement {
        Placement::centred(self.cubes.resolution, self.object_span, half_extent)
    }
}

/// What a consumer needs of a job's settings before anything is written.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JobCheck {
    /// Settings the job lacks, each `key = value` with why; the export is refused while any
    /// is listed.
    pub required: Vec<String>,
    /// What the export will not match in the consumer's own pipeline, written anyway.
    pub warnings: Vec<String>,
}

/// An item's samples with how the job drew and stored them.
#[derive(Debug, Clone, Copy)]
pub struct StoredSamples<'a> {
    /// The samples (normalized frame).
    pub samples: &'a Samples,
    /// The job's sample parameters (counts, σ lists).
    pub params: &'a SampleParams,
}

/// One file of an export.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportFile {
    /// Path relative to the export folder.
    pub path: PathBuf,
    /// The file's bytes.
    pub bytes: Vec<u8>,
}

/// The files of one item, and what the consumer's listing says of it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ItemExport {
    /// The item's files.
    pub files: Vec<ExportFile>,
    /// The item's columns in the consumer's listing (name → value), if it reads one.
    pub listing: BTreeMap<String, String>,
    /// What the files lack that some of the consumer's configs read (Step1X-3D's
    /// `sharp_surface` of an item without sharp edges), counted by the export.
    pub note: Option<&'static str>,
}

/// One exported item as the listing files see it.
#[derive(Debug, Clone, PartialEq)]
pub struct Listed {
    /// The item's id.
    pub id: String,
    /// Its file stem.
    pub stem: String,
    /// Its files, relative to the export folder.
    pub files: Vec<PathBuf>,
    /// Its listing columns ([`ItemExport::listing`]).
    pub columns: BTreeMap<String, String>,
    /// Its manifest's provenance columns (licence, source, ...; `""` for none): a listing
    /// that is a table carries them as `manifest.<name>` columns.
    pub provenance: BTreeMap<String, String>,
}

/// The entries every npz we write carries, so a file names its item: `id`, `item_index` and
/// the job's normalization (`center`, `scale`, `resolution`).
pub(crate) fn identity_arrays(item: &Item) -> Vec<npz::Array> {
    let norm = item.cubes.normalization;
    vec![
        npz::Array::text("id", item.id),
        npz::Array::numbers("item_index", "<i8", vec![], &[item.item_index as i64]),
        npz::Array::numbers("center", "<f8", vec![3], &norm.center),
        npz::Array::numbers("scale", "<f8", vec![], &[norm.scale]),
        npz::Array::numbers("resolution", "<i8", vec![], &[item.cubes.resolution as i64]),
    ]
}

/// One `.npz` file at `path` holding `arrays`.
pub(crate) fn npz_file(path: impl Into<PathBuf>, arrays: &[npz::Array]) -> Result<ExportFile> {
    Ok(ExportFile {
        path: path.into(),
        bytes: npz::npz_bytes(arrays)?,
    })
}
