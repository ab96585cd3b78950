//! The one function that touches geometry: load an item, convert it with the job's
//! parameters, extract the mesh when asked, and encode the row. It runs inside the isolated
//! item worker process ([`crate::child`]); every error becomes a `failed` row.

use sparc3d_schema::{
    EncodedTensor, ErrorClass, FrozenItem, ItemStatus, JobConfig, RowCounts, RowTensors,
    RowTimings, ShardRow,
};
use std::path::Path;
use std::time::Instant;

/// Converts one item into its shard row (timings `total_s` and `attempts` are filled in by
/// the supervisor).
pub fn convert_item(item: &FrozenItem, config: &JobConfig) -> ShardRow {
    let params = &config.params;
    let path = Path::new(&item.record.uri);
    let fail = |class: ErrorClass, message: String, timings: RowTimings| {
        let mut row = ShardRow::failed(
            item.index,
            &item.record.id,
            &item.record.uri,
            params.resolution,
            class,
            message,
        );
        row.source_sha256 = item.record.sha256.clone();
        row.timings = timings;
        row
    };
    let mut timings = RowTimings::default();
    let t = Instant::now();
    let sha = item
        .record
        .sha256
        .clone()
        .or_else(|| crate::fsutil::file_sha256(path).ok());
    let loaded = match sparcubes::io::load(path) {
        Ok(l) => l,
        Err(e) => return fail(e.class().into(), e.to_string(), timings),
    };
    let input_components =
        sparcubes::topology::check(&sparcubes::topology::weld(&loaded.mesh)).components;
    timings.load_s = t.elapsed().as_secs_f64();

    let t = Instant::now();
    let conversion = match sparcubes::convert(&loaded.mesh, params) {
        Ok(c) => c,
        Err(e) => return fail(e.class().into(), e.to_string(), timings),
    };
    timings.convert_s = t.elapsed().as_secs_f64();
    timings.stages = conversion
        .stats
        .stage_seconds
        .iter()
        .map(|(k, v)| (k.to_string(), *v))
        .collect();

    let t = Instant::now();
    let mesh = config
        .extract_mesh
        .then(|| sparcubes::extract(&conversion.cubes));
    timings.extract_s = t.elapsed().as_secs_f64();

    let t = Instant::now();
    let level = config.zstd_level;
    let encoded = RowTensors::from_cubes(&conversion.cubes, level).and_then(|mut tensors| {
        if let (true, Some(m)) = (config.store_mesh, &mesh) {
            tensors.mesh_vertices = Some(EncodedTensor::from_f32x3(&m.positions, level)?);
            tensors.mesh_faces = Some(EncodedTensor::from_u32x3(&m.triangles, level)?);
        }
        Ok(tensors)
    });
    let tensors = match encoded {
        Ok(t) => t,
        Err(e) => return fail(ErrorClass::EncodeError, e.to_string(), timings),
    };
    timings.encode_s = t.elapsed().as_secs_f64();

    let stats = &conversion.stats;
    ShardRow {
        item_index: item.index,
        id: item.record.id.clone(),
        uri: item.record.uri.clone(),
        source_sha256: sha,
        status: ItemStatus::Ok,
        error_class: None,
        error_message: None,
        stderr_tail: None,
        attempts: 1,
        resolution: params.resolution,
        normalization: Some(conversion.cubes.normalization),
        counts: Some(RowCounts {
            input_faces: loaded.mesh.triangles.len() as u64,
            input_vertices: loaded.mesh.positions.len() as u64,
            input_components: Some(input_components),
            active_vertices: conversion.cubes.coords.len() as u64,
            active_cells: conversion.cubes.cells.len() as u64,
            output_faces: mesh.as_ref().map(|m| m.triangles.len() as u64),
            shell_vertices: stats.shell_vertices,
            wall_cells: stats.wall_cells,
        }),
        timings,
        tensors: Some(tensors),
    }
}
