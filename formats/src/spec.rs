//! The terms a consumer states itself in: its [`Spec`] (its name, what it reads, its preset,
//! the functions that make its files), the parts of a spec, the job settings and condition
//! views a preset sets, and the plain functions most specs share. Each consumer module holds
//! one `SPEC` in these terms; [`crate::consumer::Consumer::ALL`] is the table of them.

use crate::{ExportFile, Frame, Item, ItemExport, JobCheck, Listed, Placement, Result};
use serde_json::{json, Map, Value};
use sparcubes::samples::SampleParams;
use sparcubes::Params;
use std::path::Path;

/// Everything the export, the presets and the `--help` texts know of one consumer.
#[derive(Debug)]
pub struct Spec {
    /// The name `--format` and `--for` take.
    pub name: &'static str,
    /// The codebase's own name, as help texts write it (`TRELLIS.2`).
    pub title: &'static str,
    /// One line for `--help`: what it writes.
    pub about: &'static str,
    /// The frames its files can be written in; the first is its default.
    pub frames: &'static [Frame],
    /// Which stored columns beyond the cubes its files are made from.
    pub reads: Reads,
    /// What `--for NAME` sets, `None` for a consumer that reads any job (cubvh).
    pub preset: Option<PresetSpec>,
    /// The `[samples]` keys a job with these samples (None: samples off) lacks for it, each
    /// with what it needs (empty when nothing is missing).
    pub missing: fn(Option<&SampleParams>) -> Vec<String>,
    /// What it says of a job converted with these params, written in this frame, before
    /// anything is written: the settings it needs and the warnings to show.
    pub check: fn(&Params, Frame) -> JobCheck,
    /// Its own files of one item, paths relative to the export folder.
    pub files: fn(&Item) -> Result<ItemExport>,
    /// Where a job's condition views go.
    pub views: Views,
    /// The listing files of the items written (in item order), empty when it reads none;
    /// the path is where the export folder ends up (absolute), for listings of paths.
    pub listing: fn(&[Listed], &Path) -> Result<Vec<ExportFile>>,
}

/// The stored columns beyond the cubes a consumer's files are made from; the export decodes
/// only those.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reads {
    /// The samples (the grid layouts are made from the sparse cubes alone).
    pub samples: bool,
    /// The appearance (the `[attributes]` columns): TRELLIS.2's PBR voxels.
    pub attributes: bool,
}

impl Reads {
    /// The cubes alone.
    pub const CUBES: Reads = Reads {
        samples: false,
        attributes: false,
    };
    /// The cubes and the samples.
    pub const SAMPLES: Reads = Reads {
        samples: true,
        attributes: false,
    };
}

/// Where the condition views of a rendered job go in a consumer's export.
#[derive(Debug, Clone, Copy)]
pub enum Views {
    /// Into its own layout of views, written by its `files` (Hunyuan3D-2.1, Step1X-3D,
    /// TRELLIS.2).
    Own,
    /// Into the plain multi-view layout ([`crate::renders::plain`]), the cameras in the frame
    /// of the geometry it writes, which this gives.
    Plain(fn(&Item) -> Placement),
}

/// What `--for NAME` (or `--for NAME@G`) sets for a consumer.
#[derive(Debug, Clone, Copy)]
pub struct PresetSpec {
    /// What it does, for `--for`'s help (consumers one after the other with the same text
    /// share it): `samples on`.
    pub help: &'static str,
    /// Whether it turns samples on (`samples.enabled = true`, whose defaults serve every
    /// vector-set consumer).
    pub samples: bool,
    /// Its condition views, used when the job renders (`--renders`).
    pub renders: Option<RenderRecipe>,
    /// The grid `@G` names, `None` for a preset that takes none.
    pub grid: Option<GridPreset>,
}

impl PresetSpec {
    /// The preset of a vector-set consumer: samples on, no grid, no views of its own.
    pub const SAMPLES: PresetSpec = PresetSpec {
        help: "samples on",
        samples: true,
        renders: None,
        grid: None,
    };
}

/// The job settings a preset sets; every other key keeps its default.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Settings {
    /// `params.resolution`.
    pub resolution: Option<u32>,
    /// `params.object_span`.
    pub object_span: Option<f64>,
    /// `params.output_span`.
    pub output_span: Option<f64>,
    /// `samples.enabled = true` (the defaults serve every vector-set consumer).
    pub samples: bool,
    /// The consumer's condition views (`[renders]` recipe, views and size), used when the
    /// job renders (`--renders`, `[renders] enabled = true`); a job that does not keeps its
    /// config and fingerprint, since a disabled section is left out of both.
    pub renders: Option<RenderRecipe>,
}

impl Settings {
    /// Nothing set (the [`Default`], for constants).
    pub const NONE: Settings = Settings {
        resolution: None,
        object_span: None,
        output_span: None,
        samples: false,
        renders: None,
    };
}

/// A consumer's condition views: whose cameras and lights, how many, how large.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RenderRecipe {
    /// `[renders] recipe` (`trellis`, `trellis2`).
    pub recipe: &'static str,
    /// Views per item.
    pub views: u32,
    /// Side of a view in pixels.
    pub size: u32,
}

/// The grid of a preset `NAME@G`, as its consumer states it: how it is written, which it
/// takes, what it sets.
#[derive(Debug, Clone, Copy)]
pub struct GridPreset {
    /// How [`Preset::forms`] writes it after the name: `@G`, or `[@N]` where it is optional.
    pub form: &'static str,
    /// Whether `--for NAME` must name it (such presets come first in `--for`'s help).
    pub required: bool,
    /// The error for a preset `text` with a grid (a whole number, 8 to the largest
    /// resolution) or none (`None`) that the consumer does not take: one it needs, or one
    /// too large; the error names the forms it takes.
    pub accept: fn(&str, Option<u32>) -> Result<()>,
    /// The `params` keys a grid (or none) sets (`resolution`, `object_span`, `output_span`;
    /// samples and renders are the [`PresetSpec`]'s).
    pub params: fn(Option<u32>) -> Settings,
    /// What a job made with this preset at grid G lacks when a config key or flag changed
    /// its settings, said in the preset's own terms rather than as the export's check says
    /// it; `None` to let the check speak.
    pub misfit: fn(u32, &Params) -> Option<String>,
}

impl Settings {
    /// The settings as a partial job config (`{"params": {...}, "samples": {...}}`), under
    /// which a config file's keys are merged.
    pub fn overrides(&self) -> Value {
        let mut params = Map::new();
        if let Some(r) = self.resolution {
            params.insert("resolution".into(), json!(r));
        }
        if let Some(s) = self.object_span {
            params.insert("object_span".into(), json!(s));
        }
        if let Some(s) = self.output_span {
            params.insert("output_span".into(), json!(s));
        }
        let mut out = Map::new();
        if !params.is_empty() {
            out.insert("params".into(), Value::Object(params));
        }
        if self.samples {
            out.insert("samples".into(), json!({"enabled": true}));
        }
        if let Some(r) = self.renders {
            out.insert(
                "renders".into(),
                json!({"recipe": r.recipe, "views": r.views, "size": r.size}),
            );
        }
        Value::Object(out)
    }
}

/// [`Views::Plain`] of a grid consumer: the cameras in the grid's frame.
pub(crate) fn grid_views(item: &Item) -> Placement {
    Placement::grid(item.cubes.resolution)
}

/// [`Spec::missing`] of a consumer made from the cubes alone: nothing.
pub(crate) fn needs_no_samples(_: Option<&SampleParams>) -> Vec<String> {
    Vec::new()
}

/// [`Spec::check`] of a consumer that takes any job: samples move into a consumer's cube
/// exactly, whatever the job's span, and cubvh's voxels are the job's grid.
pub(crate) fn takes_any_job(_: &Params, _: Frame) -> JobCheck {
    JobCheck::default()
}

/// [`Spec::listing`] of a consumer that reads no listing.
pub(crate) fn no_listing(_: &[Listed], _: &Path) -> Result<Vec<ExportFile>> {
    Ok(Vec::new())
}
