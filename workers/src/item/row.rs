//! One frozen item converted into its shard row: its bytes read or fetched and checked against
//! the sha256 frozen at `init`, taken through the conversion, every failure a `failed` row.

use super::appearance::render_request;
use super::convert::convert_bytes;
use super::steps::{Converted, Encoding, Failed, Steps};
use sparc3d_schema::{ErrorClass, FrozenItem, ItemStatus, JobConfig, RowCounts, ShardRow};
use sparcubes::io::Buffers;
use sparcubes::materials::TextureBudget;
use std::time::Instant;

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
    let source = match crate::item::source::read(item) {
        Ok(source) => source,
        Err(e) => return failed(e.class, e.message, started.elapsed().as_secs_f64()),
    };
    let crate::item::source::SourceBytes {
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
    let remote_buffers = remote.map(crate::item::source::RemoteBuffers::new);
    let read_remote = |rel: &str| match &remote_buffers {
        Some(b) => b.read(rel),
        None => Err("no remote source".to_string()),
    };
    let buffers = match remote_buffers {
        Some(_) => Buffers::Relative(&read_remote),
        None => Buffers::Folder,
    };
    let steps = match steps_of(config, memory_bytes, &sha) {
        Ok(steps) => steps,
        Err(message) => {
            let elapsed = started.elapsed().as_secs_f64();
            return failed(
                ErrorClass::Geometry(sparcubes::ErrorClass::InvalidParams),
                message,
                elapsed,
            );
        }
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
    ok_row(item, params.resolution, sha, done)
}

/// What a job's `config` asks of each item's conversion; an item whose condition views
/// cannot be asked for (`render_request`) gets the reason.
fn steps_of<'a>(
    config: &'a JobConfig,
    memory_bytes: u64,
    sha256: &str,
) -> Result<Steps<'a>, String> {
    Ok(Steps {
        params: &config.params,
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
        renders: render_request(&config.renders, sha256)?,
    })
}

/// The `ok` row of an item converted from the bytes whose sha256 is `sha`.
fn ok_row(item: &FrozenItem, resolution: u32, sha: String, done: Converted) -> ShardRow {
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
        resolution,
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
    buffers: Option<&crate::item::source::RemoteBuffers>,
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
