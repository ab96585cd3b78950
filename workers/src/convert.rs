//! The one conversion path: load a mesh file, convert it with Sparcubes, extract the mesh,
//! encode the tensors, timing each stage ([`convert_file`]). The item worker ([`convert_item`],
//! run inside the isolated process of [`crate::child`]), `sparc3d convert` and `sparc3d bench`
//! all go through it; each asks only for the steps it needs ([`Steps`]).

use sparc3d_render::cond::{asset, Request};
use sparc3d_schema::{
    AppearanceFacts, AttributeTensors, EncodedTensor, ErrorClass, FrozenItem, ItemStatus,
    JobConfig, QualityFacts, RowCounts, RowTensors, RowTimings, SampleTensors, SchemaError,
    ShardRow,
};
use sparc3d_schema::{RenderedView, RowRenders};
use sparcubes::attributes::CellAttributes;
use sparcubes::io::{Buffers, LoadStats};
use sparcubes::materials::TextureBudget;
use sparcubes::products::shape_signature::{signature_of, surface_pass};
use sparcubes::samples::{SampleParams, Samples};
use sparcubes::{Conversion, Params, TriMesh};
use std::path::Path;
use std::time::Instant;

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
    fn add(&mut self, name: &str, seconds: f64) {
        self.in_order.push((name.to_string(), seconds));
    }

    /// A stage after the conversion's own (`samples`, `attributes`): among the row's stages
    /// and in order.
    fn add_stage(&mut self, name: &str, seconds: f64) {
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

/// Loads the mesh at `path` and takes it through `steps`.
pub fn convert_file(path: &Path, steps: Steps) -> Result<Converted, Box<Failed>> {
    let started = Instant::now();
    match sparcubes::io::read_source(path) {
        Ok(bytes) => convert_bytes(bytes, path, Buffers::Folder, steps, started),
        Err(e) => Err(Box::new(Failed {
            error: StageError::Load(e),
            seconds: StageSeconds::default(),
        })),
    }
}

/// Takes the bytes read from `path` ([`sparcubes::io::read_source`] or fetched, started at
/// `started`, which the load stage's time counts from) through `steps`; they are dropped once
/// parsed. A glTF file's external buffers come from `buffers`.
pub fn convert_bytes(
    bytes: Vec<u8>,
    path: &Path,
    buffers: Buffers,
    steps: Steps,
    started: Instant,
) -> Result<Converted, Box<Failed>> {
    let mut seconds = StageSeconds::default();
    let fail = |error, seconds| Box::new(Failed { error, seconds });
    let t = started;
    let loaded = sparcubes::io::load_read_with(&bytes, path, buffers);
    let kept = (steps.attributes.is_some() || steps.renders.is_some()).then_some(bytes);
    let (source, load_stats) = match loaded {
        Ok(loaded) => (loaded.mesh, loaded.stats),
        Err(e) => return Err(fail(StageError::Load(e), seconds)),
    };
    let quality_started = Instant::now();
    let source_facts = steps.quality.then(|| crate::quality::source_facts(&source));
    let quality_s = quality_started.elapsed().as_secs_f64();
    let input_components = match &source_facts {
        Some(f) => Some(f.components),
        None => steps
            .input_components
            .then(|| sparcubes::topology::component_count(&sparcubes::topology::weld(&source))),
    };
    seconds.timings.load_s = t.elapsed().as_secs_f64() - quality_s;
    seconds.add("load", seconds.timings.load_s);

    let t = Instant::now();
    let conversion = match sparcubes::convert(&source, steps.params) {
        Ok(c) => c,
        Err(e) => return Err(fail(StageError::Convert(e), seconds)),
    };
    seconds.timings.convert_s = t.elapsed().as_secs_f64();
    let stages = conversion.stats.stage_seconds.iter();
    seconds.timings.stages = stages.map(|(k, v)| (k.to_string(), *v)).collect();
    seconds
        .in_order
        .extend(seconds.timings.stages.iter().cloned());
    let input_faces = source.triangles.len() as u64;
    let input_vertices = source.positions.len() as u64;
    drop(source);

    let t = Instant::now();
    let extract = steps.extract || steps.samples.is_some() || steps.signature;
    let mut mesh = extract.then(|| sparcubes::extract(&conversion.cubes));
    seconds.timings.extract_s = t.elapsed().as_secs_f64();
    if extract {
        seconds.add("extract", seconds.timings.extract_s);
    }
    let output_faces = mesh
        .as_ref()
        .filter(|_| steps.extract)
        .map(|m| m.triangles.len() as u64);
    let source = source_facts.map(|facts| (facts, quality_s));
    let (quality, signature) = measure_output(
        &steps,
        mesh.as_ref(),
        source,
        &load_stats,
        &conversion,
        &mut seconds,
    );
    let samples = match samples_of(steps.samples, &conversion, mesh.as_ref(), &mut seconds) {
        Ok(s) => s,
        Err(e) => return Err(fail(StageError::Samples(e), seconds)),
    };
    let (attributes, renders) = match kept.as_deref() {
        Some(bytes) => {
            let source = Source {
                bytes,
                path,
                buffers,
            };
            match appearance_products(&source, &steps, &conversion, &mut seconds) {
                Ok(products) => products,
                Err(e) => return Err(fail(e, seconds)),
            }
        }
        None => (None, None),
    };
    let store_mesh = steps.encode.is_some_and(|e| e.store_mesh);
    if !(steps.keep_mesh || store_mesh) {
        mesh = None;
    }

    let tensors = match steps.encode {
        None => None,
        Some(encoding) => {
            let t = Instant::now();
            let drawn = samples.as_ref().zip(steps.samples);
            let cells = attributes.as_ref().map(|a| &a.0);
            match encode(&conversion, mesh.as_ref(), drawn, cells, encoding) {
                Ok(mut tensors) => {
                    tensors.renders = renders;
                    seconds.timings.encode_s = t.elapsed().as_secs_f64();
                    seconds.add("encode", seconds.timings.encode_s);
                    Some(tensors)
                }
                Err(e) => return Err(fail(StageError::Encode(e), seconds)),
            }
        }
    };
    Ok(Converted {
        load_stats,
        input_faces,
        input_vertices,
        input_components,
        conversion,
        output_faces,
        mesh: if steps.keep_mesh { mesh } else { None },
        tensors,
        attributes,
        quality,
        signature,
        seconds,
    })
}

/// The quality facts (given the `source`'s, measured in `seconds` before the conversion) and
/// the shape signature of the extracted `mesh`, as `steps` asks, timed as the stages `quality`
/// and `signature`. Both read one pass over the output's triangles (`surface_pass`: the volume
/// for both, the area and the sample for the signature), timed with the quality facts when
/// they are asked for (the pass is theirs; taking the sample on the way adds little:
/// docs/PERFORMANCE.md, "Near-duplicate groups") and with the signature otherwise. The
/// signature is read right after the pass, while its sample is still in the cache.
fn measure_output(
    steps: &Steps,
    mesh: Option<&TriMesh>,
    source: Option<(crate::quality::SourceFacts, f64)>,
    load_stats: &LoadStats,
    conversion: &Conversion,
    seconds: &mut StageSeconds,
) -> (Option<QualityFacts>, Option<Vec<f32>>) {
    let t = Instant::now();
    let pass = mesh
        .filter(|_| steps.quality || steps.signature)
        .map(|m| surface_pass(m, steps.signature));
    let pass_s = t.elapsed().as_secs_f64();
    let (pass_for_quality, pass_for_signature) = match source {
        Some(_) => (pass_s, 0.0),
        None => (0.0, pass_s),
    };
    let t = Instant::now();
    let signature = pass
        .as_ref()
        .filter(|_| steps.signature)
        .and_then(signature_of);
    let signature_s = pass_for_signature + t.elapsed().as_secs_f64();
    let quality = source.map(|(source, source_s)| {
        let t = Instant::now();
        let cubes = &conversion.cubes;
        let output = mesh.zip(pass.as_ref()).map(|(m, p)| {
            crate::quality::output_facts(m, p.volume, &cubes.normalization, cubes.resolution)
        });
        let facts = crate::quality::facts(&source, load_stats, &conversion.stats, output);
        seconds.add_stage(
            "quality",
            source_s + pass_for_quality + t.elapsed().as_secs_f64(),
        );
        facts
    });
    if signature.is_some() {
        seconds.add_stage("signature", signature_s);
    }
    (quality, signature.map(|s| s.to_vec()))
}

/// Draws the samples (`params`, a job with `[samples]`) from the extracted `mesh` and the
/// converted cubes, timed as the stage `samples`; none when either is missing.
fn samples_of(
    params: Option<&SampleParams>,
    conversion: &Conversion,
    mesh: Option<&TriMesh>,
    seconds: &mut StageSeconds,
) -> Result<Option<Samples>, sparcubes::Error> {
    let (Some(params), Some(m)) = (params, mesh) else {
        return Ok(None);
    };
    let t = Instant::now();
    let samples = sparcubes::samples::sample(&conversion.cubes, m, params)?;
    seconds.add_stage("samples", t.elapsed().as_secs_f64());
    Ok(Some(samples))
}

/// The attributes of the active cells and what the appearance is made of.
type Sampled = (CellAttributes, AppearanceFacts);

/// The source's bytes kept for the stages after the conversion, and where they came from.
struct Source<'a> {
    bytes: &'a [u8],
    path: &'a Path,
    buffers: Buffers<'a>,
}

/// The attributes and the condition views `steps` asks for, from the source's bytes parsed
/// again: its appearance is read once for both, and timed with the attributes when they are
/// asked for, else with the views. Attributes fail the item when the appearance cannot be
/// read; views are then drawn in the plain grey.
fn appearance_products(
    source: &Source,
    steps: &Steps,
    conversion: &Conversion,
    seconds: &mut StageSeconds,
) -> Result<(Option<Sampled>, Option<RowRenders>), StageError> {
    let t = Instant::now();
    let budget = steps.attributes.unwrap_or_default();
    let read = sparcubes::materials::read_within(source.bytes, source.path, source.buffers, budget);
    let (appearance, read_error) = match read {
        Ok(a) => (Some(a), None),
        Err(e) if steps.attributes.is_some() => return Err(StageError::Attributes(e)),
        Err(e) => (None, Some(e)),
    };
    let attributes = appearance
        .as_ref()
        .filter(|_| steps.attributes.is_some())
        .map(|a| {
            let cells = sparcubes::attributes::sample(&conversion.cubes, a);
            let facts = AppearanceFacts::new(&a.facts, &cells);
            seconds.add_stage("attributes", t.elapsed().as_secs_f64());
            (cells, facts)
        });
    let renders = match &steps.renders {
        Some(request) => {
            let not_read = match (&read_error, &appearance) {
                (Some(e), _) => vec![format!(
                    "the appearance could not be read ({e}): the views are in the plain grey"
                )],
                (None, Some(a)) => a.facts.not_read.clone(),
                (None, None) => Vec::new(),
            };
            let coloured = appearance.and_then(asset::with_colours);
            let since = match steps.attributes {
                Some(_) => Instant::now(),
                None => t,
            };
            let mut views = renders_of(source, coloured.as_ref(), request, since, seconds)?;
            views.not_read = not_read;
            Some(views)
        }
        None => None,
    };
    Ok((attributes, renders))
}

/// The condition views of the source (parsed again from its bytes) in `appearance`'s
/// colours, timed from `since` as the stage `renders`; a view that sees nothing fails them.
fn renders_of(
    source: &Source,
    appearance: Option<&sparcubes::materials::Appearance>,
    request: &Request,
    since: Instant,
    seconds: &mut StageSeconds,
) -> Result<RowRenders, StageError> {
    let mesh = sparcubes::io::load_read_with(source.bytes, source.path, source.buffers)
        .map_err(StageError::Load)?
        .mesh;
    let views =
        asset::render_asset(&mesh, appearance, request).map_err(StageError::RenderEncode)?;
    if let Some(problem) = views.problem() {
        return Err(StageError::Renders(problem));
    }
    seconds.add_stage("renders", since.elapsed().as_secs_f64());
    Ok(RowRenders {
        views: views
            .pngs
            .into_iter()
            .zip(views.seconds)
            .map(|(png, seconds)| RenderedView { png, seconds })
            .collect(),
        transforms: views.transforms,
        not_read: Vec::new(),
    })
}

/// The cubes' tensors, with the mesh's when it is to be stored.
fn encode(
    conversion: &Conversion,
    mesh: Option<&TriMesh>,
    samples: Option<(&Samples, &SampleParams)>,
    cells: Option<&CellAttributes>,
    encoding: Encoding,
) -> Result<RowTensors, SchemaError> {
    let level = encoding.zstd_level;
    let mut tensors = RowTensors::from_cubes(&conversion.cubes, level)?;
    if let (true, Some(m)) = (encoding.store_mesh, mesh) {
        tensors.mesh_vertices = Some(EncodedTensor::from_f32x3(&m.positions, level)?);
        tensors.mesh_faces = Some(EncodedTensor::from_u32x3(&m.triangles, level)?);
    }
    if let Some((s, params)) = samples {
        tensors.samples = Some(SampleTensors::from_samples(s, params, level)?);
    }
    if let Some(a) = cells {
        tensors.attributes = Some(AttributeTensors::from_attributes(a, level)?);
    }
    Ok(tensors)
}

/// Converts one item into its shard row (timings `total_s` and `attempts` are filled in by
/// the supervisor); every error becomes a `failed` row. The bytes converted are the bytes
/// hashed: a file whose sha256 is not the one frozen at `init` is a `source_changed` row,
/// never converted under the item's id (`check_source`); an ok row's `source_sha256` is
/// the hash of the bytes it was converted from. `memory_bytes` is the item's memory limit
/// (0: none), a quarter of which bounds its decoded textures ([`TextureBudget`]).
pub fn convert_item(item: &FrozenItem, config: &JobConfig, memory_bytes: u64) -> ShardRow {
    let params = &config.params;
    let started = Instant::now();
    let failed = |class, message: String, load_s: f64| {
        let mut row = ShardRow::failed_item(item, params.resolution, class, message);
        row.timings.load_s = load_s;
        row
    };
    let source = match crate::source::read(item) {
        Ok(source) => source,
        Err(e) => return failed(e.class, e.message, started.elapsed().as_secs_f64()),
    };
    let crate::source::SourceBytes {
        bytes,
        sha256,
        path,
        remote,
    } = source;
    let path = path.as_path();
    let sha = sha256.unwrap_or_else(|| crate::fsutil::bytes_sha256(&bytes));
    if let Err(message) = check_source(item, &sha) {
        let mut row = failed(
            ErrorClass::SourceChanged,
            message,
            started.elapsed().as_secs_f64(),
        );
        row.source_sha256 = Some(sha);
        return row;
    }
    let remote_buffers = remote.map(crate::source::RemoteBuffers::new);
    let read_remote = |rel: &str| match &remote_buffers {
        Some(b) => b.read(rel),
        None => Err("no remote source".to_string()),
    };
    let buffers = match remote_buffers {
        Some(_) => Buffers::Relative(&read_remote),
        None => Buffers::Folder,
    };
    let steps = Steps {
        params,
        input_components: true,
        extract: config.extract_mesh,
        samples: config.samples.enabled.then_some(&config.samples.params),
        keep_mesh: false,
        encode: Some(Encoding {
            zstd_level: config.zstd_level,
            store_mesh: config.store_mesh,
        }),
        attributes: config
            .attributes
            .enabled
            .then(|| TextureBudget::within_item_memory(memory_bytes)),
        quality: config.quality,
        signature: config.shape_signature,
        renders: match render_request(&config.renders, &sha) {
            Ok(r) => r,
            Err(message) => {
                let elapsed = started.elapsed().as_secs_f64();
                return failed(
                    ErrorClass::Geometry(sparcubes::ErrorClass::InvalidParams),
                    message,
                    elapsed,
                );
            }
        },
    };
    let done = match convert_bytes(bytes, path, buffers, steps, started) {
        Ok(done) => done,
        Err(failure) => {
            let Failed { error, seconds } = *failure;
            // A glTF buffer that could not be fetched fails the item as a fetch.
            let fetch_failed = remote_buffers.as_ref().and_then(|b| b.failure()).is_some();
            let class = if fetch_failed {
                ErrorClass::Fetch
            } else {
                error.class()
            };
            let mut row = failed(class, error.to_string(), 0.0);
            row.timings = seconds.timings;
            return row;
        }
    };
    if let Some(message) = appearance_not_fetched(remote_buffers.as_ref(), item) {
        let mut row = failed(ErrorClass::Fetch, message, 0.0);
        row.timings = done.seconds.timings;
        return row;
    }
    let cubes = &done.conversion.cubes;
    let stats = &done.conversion.stats;
    ShardRow {
        item_index: item.index,
        id: item.record.id.clone(),
        uri: item.record.uri.clone(),
        source_sha256: Some(sha),
        status: ItemStatus::Ok,
        error_class: None,
        error_message: None,
        stderr_tail: None,
        attempts: 1,
        resolution: params.resolution,
        normalization: Some(cubes.normalization),
        counts: Some(RowCounts {
            input_faces: done.input_faces,
            input_vertices: done.input_vertices,
            input_components: done.input_components,
            active_vertices: cubes.coords.len() as u64,
            active_cells: cubes.cells.len() as u64,
            output_faces: done.output_faces,
            shell_vertices: stats.shell_vertices,
            wall_cells: stats.wall_cells,
        }),
        timings: done.seconds.timings,
        tensors: done.tensors,
        provenance: Default::default(),
        appearance: done.attributes.map(|a| a.1),
        quality: done.quality,
        shape_signature: done.signature,
    }
}

/// Why an item that converted is a `fetch` failure all the same: a file beside its remote
/// source that its appearance reads (a texture, an OBJ's material library) could not be
/// downloaded, as a glTF buffer that cannot be is (issue 64 item 2), so that `retry --class
/// fetch` queues it rather than an `ok` row without that appearance. A file over the byte cap
/// is not retried: it stays named in the row's `appearance_not_read`.
fn appearance_not_fetched(
    buffers: Option<&crate::source::RemoteBuffers>,
    item: &FrozenItem,
) -> Option<String> {
    let e = buffers?.failure()?;
    if e.kind == sparc3d_sources::FetchErrorKind::TooLarge {
        return None;
    }
    Some(format!(
        "{}: a file its appearance reads could not be downloaded: {e}; its shape converted, \
         and `sparc3d retry JOB --class fetch` converts it again once the file can be fetched",
        item.record.uri
    ))
}

/// The render request of a job's `[renders]` for a source whose sha256 is `sha` (hex): the
/// item's seed is the head of that sha256 mixed with the section's seed, as `sparc3d render`
/// seeds a file. `None` when the job renders nothing.
fn render_request(
    config: &sparc3d_schema::RenderConfig,
    sha: &str,
) -> Result<Option<Request>, String> {
    if !config.enabled {
        return Ok(None);
    }
    let recipe = sparc3d_render::cond::Recipe::named(&config.recipe)
        .ok_or_else(|| format!("renders.recipe {:?} names no render recipe", config.recipe))?;
    let mut head = [0u8; 8];
    for (i, b) in head.iter_mut().enumerate() {
        *b = sha
            .get(2 * i..2 * i + 2)
            .and_then(|h| u8::from_str_radix(h, 16).ok())
            .ok_or_else(|| format!("the source's sha256 {sha:?} is not hex"))?;
    }
    Ok(Some(Request {
        recipe,
        views: config.views,
        size: config.size,
        seed: asset::seed_of(head, config.seed),
        passes: Default::default(),
    }))
}

/// Refuses bytes whose sha256 (`found`) is not the one the item was frozen with: the file
/// changed after the manifest was made (or its sha256 column is wrong), and the item's id
/// stands for the frozen bytes. An item frozen without a sha256 (a manifest with ids and no
/// sha256 column) has nothing to compare with. Only the file the manifest names is hashed;
/// a glTF file's external buffers are not part of its sha256 (docs/RELIABILITY.md).
fn check_source(item: &FrozenItem, found: &str) -> Result<(), String> {
    match &item.record.sha256 {
        Some(frozen) if !frozen.eq_ignore_ascii_case(found) => Err(format!(
            "{}: the file's sha256 is {found}, not {frozen} as the manifest froze it: the file \
             changed after the manifest was made, so it was not converted under its id; restore \
             it and `sparc3d retry JOB --class source_changed`, or convert the new file in a \
             new job",
            item.record.uri
        )),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example(name: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../examples")
            .join(name)
    }

    #[test]
    fn the_path_runs_the_steps_asked_for_in_order() -> Result<(), Box<dyn std::error::Error>> {
        let params = Params::with_resolution(32);
        let mut steps = Steps {
            params: &params,
            input_components: true,
            extract: true,
            samples: None,
            keep_mesh: false,
            encode: Some(Encoding {
                zstd_level: 3,
                store_mesh: true,
            }),
            attributes: None,
            quality: false,
            signature: false,
            renders: None,
        };
        let done = convert_file(&example("cube.off"), steps).map_err(|f| f.error)?;
        let names: Vec<&str> = done
            .seconds
            .in_order
            .iter()
            .map(|(k, _)| k.as_str())
            .collect();
        assert_eq!(names.first(), Some(&"load"));
        assert_eq!(names[names.len() - 2..], ["extract", "encode"]);
        assert_eq!(names.len() - 3, done.conversion.stats.stage_seconds.len());
        assert_eq!((done.input_faces, done.input_components), (12, Some(1)));
        assert!(done.mesh.is_none(), "not kept");
        let tensors = done.tensors.ok_or("no tensors")?;
        assert!(tensors.mesh_faces.is_some(), "stored although not kept");
        assert!(done.output_faces.is_some_and(|n| n > 0));

        steps.encode = None;
        steps.keep_mesh = true;
        let kept = convert_file(&example("cube.off"), steps).map_err(|f| f.error)?;
        assert_eq!(
            kept.mesh.map(|m| m.triangles.len() as u64),
            done.output_faces
        );
        assert_eq!(kept.conversion.cubes.coords, done.conversion.cubes.coords);
        Ok(())
    }

    #[test]
    fn the_signature_shares_the_quality_facts_volume_and_changes_none_of_them(
    ) -> Result<(), Box<dyn std::error::Error>> {
        let params = Params::with_resolution(32);
        let steps = |quality, signature| Steps {
            params: &params,
            input_components: false,
            extract: true,
            samples: None,
            keep_mesh: true,
            encode: None,
            attributes: None,
            quality,
            signature,
            renders: None,
        };
        let both = convert_file(&example("sphere.obj"), steps(true, true)).map_err(|f| f.error)?;
        let quality =
            convert_file(&example("sphere.obj"), steps(true, false)).map_err(|f| f.error)?;
        let alone =
            convert_file(&example("sphere.obj"), steps(false, true)).map_err(|f| f.error)?;
        assert_eq!(
            both.quality, quality.quality,
            "the same facts with the signature"
        );
        assert!(alone.quality.is_none() && quality.signature.is_none());
        let mesh = both.mesh.as_ref().ok_or("no mesh")?;
        let want = sparcubes::products::shape_signature::shape_signature(mesh).map(|s| s.to_vec());
        assert!(want.is_some());
        assert_eq!(both.signature, want);
        assert_eq!(alone.signature, want);
        let stages = |c: &Converted| {
            c.seconds
                .in_order
                .iter()
                .map(|(k, _)| k.clone())
                .collect::<Vec<_>>()
        };
        assert!(stages(&both).ends_with(&["quality".to_string(), "signature".to_string()]));
        assert!(stages(&alone).ends_with(&["signature".to_string()]));
        Ok(())
    }

    #[test]
    fn a_refined_row_gives_back_the_refined_mesh() -> Result<(), Box<dyn std::error::Error>> {
        // The refinement runs inside the conversion, so the row stores its displacements and
        // decoding the row extracts the mesh the conversion gave (what `show` relies on).
        let params = Params {
            refine: Some(sparcubes::refine::RefineParams {
                views: 6,
                image: Some(64),
                steps: 5,
                rate: 0.05,
            }),
            ..Params::with_resolution(32)
        };
        let steps = Steps {
            params: &params,
            input_components: false,
            extract: true,
            samples: None,
            keep_mesh: true,
            encode: Some(Encoding {
                zstd_level: 3,
                store_mesh: false,
            }),
            attributes: None,
            quality: false,
            signature: false,
            renders: None,
        };
        let done = convert_file(&example("cube.off"), steps).map_err(|f| f.error)?;
        let stats = done
            .conversion
            .stats
            .refine
            .as_ref()
            .ok_or("no refine stats")?;
        assert!(stats.moved_vertices > 0, "{stats:?}");
        let cubes = &done.conversion.cubes;
        let decoded = done
            .tensors
            .ok_or("no tensors")?
            .to_cubes(cubes.resolution, cubes.normalization)?;
        assert_eq!(&decoded, cubes);
        assert_eq!(Some(sparcubes::extract(&decoded)), done.mesh);
        Ok(())
    }

    #[test]
    fn a_job_may_name_every_render_recipe_and_no_other() {
        let names: Vec<&str> = sparc3d_render::cond::Recipe::ALL
            .iter()
            .map(|(n, _)| *n)
            .collect();
        assert_eq!(names, sparc3d_schema::RenderConfig::RECIPES);
        let on = sparc3d_schema::RenderConfig {
            enabled: true,
            ..Default::default()
        };
        let sha = "0102030405060708".to_string() + &"0".repeat(48);
        let request = render_request(&on, &sha).unwrap().unwrap();
        assert_eq!(request.seed, asset::seed_of([1, 2, 3, 4, 5, 6, 7, 8], 0));
        assert!(render_request(&on, "zz").is_err());
        let off = sparc3d_schema::RenderConfig::default();
        assert!(render_request(&off, &sha).unwrap().is_none());
    }

    #[test]
    fn a_failure_names_its_stage_and_class() {
        let params = Params::with_resolution(32);
        let steps = Steps {
            params: &params,
            input_components: false,
            extract: false,
            samples: None,
            keep_mesh: false,
            encode: None,
            attributes: None,
            quality: false,
            signature: false,
            renders: None,
        };
        let Err(failed) = convert_file(&example("missing.obj"), steps) else {
            panic!("a missing file converted")
        };
        assert!(matches!(failed.error, StageError::Load(_)));
        assert_eq!(
            failed.error.class(),
            ErrorClass::Geometry(sparcubes::ErrorClass::IoError)
        );
        assert!(failed.seconds.in_order.is_empty());
    }
}
