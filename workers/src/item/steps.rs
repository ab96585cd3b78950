//! What a conversion is asked to do and what it gives back: the steps ([`Steps`], [`Encoding`]),
//! the seconds of each stage, the converted item and how a stage fails.

use sparc3d_render::cond::Request;
use sparc3d_schema::{
    AppearanceFacts, ErrorClass, QualityFacts, RowTensors, RowTimings, SchemaError,
};
use sparcubes::attributes::CellAttributes;
use sparcubes::io::LoadStats;
use sparcubes::materials::TextureBudget;
use sparcubes::samples::SampleParams;
use sparcubes::{Conversion, Params, TriMesh};

/// What [`convert_file`] does beyond load and convert.
#[derive(Debug, Clone, Copy)]
pub struct Steps<'a> {
    /// Conversion parameters.
    pub params: &'a Params,
    /// Count the input's connected components (welded), timed as part of `load`.
    pub input_components: bool,
    /// Extract the watertight mesh from the cubes.
    pub extract: bool,
    /// Draw vector-set samples from the extracted mesh (a job with `[samples]`); the mesh is
    /// then extracted whatever [`Steps::extract`] says.
    pub samples: Option<&'a SampleParams>,
    /// Hand the extracted mesh back ([`Converted::mesh`]); otherwise it is dropped as soon as
    /// it is no longer needed, so that it does not count in the peak memory of later stages.
    pub keep_mesh: bool,
    /// Encode the tensors, and how.
    pub encode: Option<Encoding>,
    /// Sample the source's appearance at the active cells (a job with `[attributes]`,
    /// `convert --attributes`): its bytes are kept until the conversion is done and parsed
    /// again for materials then, so the conversion's peak memory does not hold them parsed.
    /// `Some` holds the texture pixels the item may decode (a quarter of its memory limit).
    pub attributes: Option<TextureBudget>,
    /// Measure the quality facts (a job with `quality = true`): the source's topology, bounds
    /// and area, and the extracted mesh's volume and components (when it is extracted), timed
    /// as the stage `quality`. The input's components then come from the same topology check.
    pub quality: bool,
    /// Compute the output's shape signature (a job with `shape_signature = true`: a shard
    /// row's `shape_signature`, for `sparc3d dedup`), timed as the stage `signature`; the
    /// mesh is then extracted whatever [`Steps::extract`] says.
    pub signature: bool,
    /// Render the source's condition views (a job with `[renders]`), timed as the stage
    /// `renders` and stored with the tensors ([`RowTensors::renders`]): the source is parsed
    /// again after the conversion, as for the attributes, and shares their appearance.
    pub renders: Option<Request>,
}

/// How [`convert_file`] encodes the tensors.
#[derive(Debug, Clone, Copy)]
pub struct Encoding {
    /// zstd level of the tensor blobs.
    pub zstd_level: i32,
    /// Also store the extracted mesh (when it was extracted).
    pub store_mesh: bool,
}

/// Seconds of each stage, both as a shard row stores them and in order as they ran.
#[derive(Debug, Clone, Default)]
pub struct StageSeconds {
    /// The row's timings (`total_s` is the supervisor's to fill in).
    pub timings: RowTimings,
    /// `load`, the conversion stages, then `extract` and `encode` when they ran.
    pub in_order: Vec<(String, f64)>,
}

impl StageSeconds {
    pub(crate) fn add(&mut self, name: &str, seconds: f64) {
        self.in_order.push((name.to_string(), seconds));
    }

    /// A stage after the conversion's own (`samples`, `attributes`): among the row's stages
    /// and in order.
    pub(crate) fn add_stage(&mut self, name: &str, seconds: f64) {
        self.timings.stages.push((name.to_string(), seconds));
        self.add(name, seconds);
    }
}

/// A mesh file through the steps asked for.
#[derive(Debug)]
pub struct Converted {
    /// What loading skipped or repaired.
    pub load_stats: LoadStats,
    /// Triangles of the loaded mesh.
    pub input_faces: u64,
    /// Vertices of the loaded mesh.
    pub input_vertices: u64,
    /// Connected components of the welded input, when asked for.
    pub input_components: Option<u64>,
    /// The sparse cubes and the conversion's counts and stage times.
    pub conversion: Conversion,
    /// Triangles of the extracted mesh, when extracted.
    pub output_faces: Option<u64>,
    /// The extracted mesh in grid coordinates, when extracted and [`Steps::keep_mesh`].
    pub mesh: Option<TriMesh>,
    /// The encoded tensors, when encoded.
    pub tensors: Option<RowTensors>,
    /// The attributes of the active cells and what the appearance is made of, when sampled.
    pub attributes: Option<(CellAttributes, AppearanceFacts)>,
    /// The quality facts, when measured.
    pub quality: Option<QualityFacts>,
    /// The output's shape signature, when asked for and the output has a surface.
    pub signature: Option<Vec<f32>>,
    /// Seconds per stage.
    pub seconds: StageSeconds,
}

/// The stage that failed, with the library's error (shown as that error).
#[derive(Debug, thiserror::Error)]
pub enum StageError {
    /// Reading or parsing the file.
    #[error(transparent)]
    Load(sparcubes::Error),
    /// The conversion.
    #[error(transparent)]
    Convert(sparcubes::Error),
    /// Drawing the samples.
    #[error("samples: {0}")]
    Samples(sparcubes::Error),
    /// Reading the appearance for the attributes.
    #[error("attributes: {0}")]
    Attributes(sparcubes::Error),
    /// The condition views: one sees nothing of the asset.
    #[error("renders: {0}")]
    Renders(String),
    /// Encoding a condition view.
    #[error("renders: {0}")]
    RenderEncode(String),
    /// Encoding the tensors.
    #[error(transparent)]
    Encode(SchemaError),
}

impl StageError {
    /// The error class a failed row records.
    pub fn class(&self) -> ErrorClass {
        match self {
            StageError::Load(e)
            | StageError::Convert(e)
            | StageError::Samples(e)
            | StageError::Attributes(e) => e.class().into(),
            StageError::Renders(_) => sparcubes::ErrorClass::EmptyMesh.into(),
            StageError::Encode(_) | StageError::RenderEncode(_) => ErrorClass::EncodeError,
        }
    }
}

/// A failed [`convert_file`]: the error and the seconds of the stages that ran before it.
#[derive(Debug)]
pub struct Failed {
    /// What failed.
    pub error: StageError,
    /// Seconds of the stages that finished.
    pub seconds: StageSeconds,
}

/// The attributes of the active cells and what the appearance is made of.
pub(crate) type Sampled = (CellAttributes, AppearanceFacts);
