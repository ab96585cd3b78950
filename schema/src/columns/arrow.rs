//! The Arrow schema of a shard row, and conversion between [`ShardRow`]s and record batches.

use crate::columns as c;
use crate::columns::tensors::{col, read_tensor, tensor_arrays, tensor_fields};
use crate::error::{Result, SchemaError};
use crate::row::class::{ErrorClass, ItemStatus};
use crate::row::tensor::EncodedTensor;
use crate::row::{RowCounts, RowTensors, RowTimings, SampleTensors, ShardRow};
use arrow_array::{
    Array, ArrayRef, Float64Array, RecordBatch, StringArray, UInt32Array, UInt64Array,
};
use arrow_schema::{DataType, Field, Schema, SchemaRef};
use sparcubes::{Normalization, SparseCubes};
use std::sync::Arc;

/// The Arrow schema of a shard without provenance columns (without key-value metadata).
pub fn schema() -> SchemaRef {
    schema_with(&[])
}

/// The Arrow schema of a shard whose items have the provenance columns `provenance` (manifest
/// column names, in order): [`schema`]'s columns, then one nullable `utf8` column
/// `manifest.<name>` each.
pub fn schema_with(provenance: &[String]) -> SchemaRef {
    schema_for(provenance, Sections::default())
}

/// The optional groups of columns a job's shards hold, as its config decides.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Sections {
    /// The appearance columns ([`crate::columns::attributes`]), a job with `[attributes]`.
    pub attributes: bool,
    /// The quality columns ([`crate::row::quality`]), a job with `quality = true`.
    pub quality: bool,
    /// The `shape_signature` column ([`crate::columns::signature`]), a job with
    /// `shape_signature = true`.
    pub signature: bool,
    /// The render columns ([`crate::columns::renders`]), a job with `[renders]`.
    pub renders: bool,
}

impl Sections {
    /// The sections a job with `config` writes.
    pub fn of(config: &crate::JobConfig) -> Self {
        Self {
            attributes: config.attributes.enabled,
            quality: config.quality,
            signature: config.shape_signature,
            renders: config.renders.enabled,
        }
    }
}

/// [`schema_with`], with the appearance columns ([`crate::columns::attributes`]), the quality
/// columns ([`crate::row::quality`]) and then the `shape_signature` column
/// ([`crate::columns::signature`]) after the tensors, as `sections` asks; without them the
/// schema is exactly [`schema_with`]'s.
pub fn schema_for(provenance: &[String], sections: Sections) -> SchemaRef {
    use DataType::*;
    let mut f = vec![
        Field::new(c::ITEM_INDEX, UInt64, false),
        Field::new(c::ID, Utf8, false),
        Field::new(c::URI, Utf8, false),
        Field::new(c::SOURCE_SHA256, Utf8, true),
        Field::new(c::STATUS, Utf8, false),
        Field::new(c::ERROR_CLASS, Utf8, true),
        Field::new(c::ERROR_MESSAGE, Utf8, true),
        Field::new(c::STDERR_TAIL, Utf8, true),
        Field::new(c::ATTEMPTS, UInt32, false),
        Field::new(c::RESOLUTION, UInt32, false),
        Field::new(c::CENTER_X, Float64, true),
        Field::new(c::CENTER_Y, Float64, true),
        Field::new(c::CENTER_Z, Float64, true),
        Field::new(c::SCALE, Float64, true),
    ];
    for name in COUNT_COLUMNS {
        f.push(Field::new(name, UInt64, true));
    }
    for name in TIME_COLUMNS {
        f.push(Field::new(name, Float64, false));
    }
    f.push(Field::new(c::TIME_STAGES, Utf8, false));
    for t in c::tensors() {
        f.extend(tensor_fields(t));
    }
    if sections.attributes {
        f.extend(crate::columns::attributes::fields());
    }
    if sections.quality {
        f.extend(crate::columns::quality::QUALITY.fields());
    }
    if sections.signature {
        f.extend(crate::columns::signature::SIGNATURE.fields());
    }
    if sections.renders {
        f.extend(crate::columns::renders::RENDERS.fields());
    }
    for name in provenance {
        f.push(Field::new(c::provenance_column(name), Utf8, true));
    }
    Arc::new(Schema::new(f))
}

const COUNT_COLUMNS: [&str; 8] = [
    c::INPUT_FACES,
    c::INPUT_VERTICES,
    c::INPUT_COMPONENTS,
    c::ACTIVE_VERTICES,
    c::ACTIVE_CELLS,
    c::OUTPUT_FACES,
    c::SHELL_VERTICES,
    c::WALL_CELLS,
];

const TIME_COLUMNS: [&str; 5] = [
    c::TIME_LOAD,
    c::TIME_CONVERT,
    c::TIME_EXTRACT,
    c::TIME_ENCODE,
    c::TIME_TOTAL,
];

/// The counts of a row in column order (the optional ones as `None` when unknown).
pub(crate) fn count_values(k: &RowCounts) -> [Option<u64>; 8] {
    [
        Some(k.input_faces),
        Some(k.input_vertices),
        k.input_components,
        Some(k.active_vertices),
        Some(k.active_cells),
        k.output_faces,
        Some(k.shell_vertices),
        Some(k.wall_cells),
    ]
}

fn time_values(t: &RowTimings) -> [f64; 5] {
    [t.load_s, t.convert_s, t.extract_s, t.encode_s, t.total_s]
}

fn stages_json(t: &RowTimings) -> String {
    let map: serde_json::Map<String, serde_json::Value> = t
        .stages
        .iter()
        .map(|(k, v)| (k.clone(), serde_json::json!(v)))
        .collect();
    serde_json::Value::Object(map).to_string()
}

fn tensor_of<'a>(row: &'a ShardRow, stem: &str) -> Option<&'a EncodedTensor> {
    let t = row.tensors.as_ref()?;
    t.iter().into_iter().find(|(s, _)| *s == stem)?.1
}

/// Builds a record batch of rows (in the given order) with [`schema`].
pub fn rows_to_batch(rows: &[ShardRow]) -> Result<RecordBatch> {
    rows_to_batch_with(rows, &[])
}

/// Builds a record batch of rows (in the given order) with [`schema_with`]`(provenance)`: a
/// row without a value for one of the columns holds null there.
pub fn rows_to_batch_with(rows: &[ShardRow], provenance: &[String]) -> Result<RecordBatch> {
    rows_to_batch_for(rows, provenance, Sections::default())
}

/// [`rows_to_batch_with`] with [`schema_for`]`(provenance, sections)`.
pub fn rows_to_batch_for(
    rows: &[ShardRow],
    provenance: &[String],
    sections: Sections,
) -> Result<RecordBatch> {
    let strs = |f: &dyn Fn(&ShardRow) -> Option<&str>| -> ArrayRef {
        Arc::new(StringArray::from(rows.iter().map(f).collect::<Vec<_>>()))
    };
    let norm = |f: &dyn Fn(&Normalization) -> f64| -> ArrayRef {
        Arc::new(Float64Array::from(
            rows.iter()
                .map(|r| r.normalization.as_ref().map(f))
                .collect::<Vec<_>>(),
        ))
    };
    let mut cols: Vec<ArrayRef> = vec![
        Arc::new(UInt64Array::from(
            rows.iter().map(|r| r.item_index).collect::<Vec<_>>(),
        )),
        strs(&|r| Some(r.id.as_str())),
        strs(&|r| Some(r.uri.as_str())),
        strs(&|r| r.source_sha256.as_deref()),
        strs(&|r| Some(r.status.as_str())),
        strs(&|r| r.error_class.map(ErrorClass::as_str)),
        strs(&|r| r.error_message.as_deref()),
        strs(&|r| r.stderr_tail.as_deref()),
        Arc::new(UInt32Array::from(
            rows.iter().map(|r| r.attempts).collect::<Vec<_>>(),
        )),
        Arc::new(UInt32Array::from(
            rows.iter().map(|r| r.resolution).collect::<Vec<_>>(),
        )),
        norm(&|n| n.center[0]),
        norm(&|n| n.center[1]),
        norm(&|n| n.center[2]),
        norm(&|n| n.scale),
    ];
    for i in 0..COUNT_COLUMNS.len() {
        cols.push(Arc::new(UInt64Array::from(
            rows.iter()
                .map(|r| r.counts.as_ref().and_then(|k| count_values(k)[i]))
                .collect::<Vec<_>>(),
        )));
    }
    for i in 0..TIME_COLUMNS.len() {
        cols.push(Arc::new(Float64Array::from(
            rows.iter()
                .map(|r| time_values(&r.timings)[i])
                .collect::<Vec<_>>(),
        )));
    }
    cols.push(Arc::new(StringArray::from(
        rows.iter()
            .map(|r| stages_json(&r.timings))
            .collect::<Vec<_>>(),
    )));
    for stem in c::tensors() {
        let ts: Vec<Option<&EncodedTensor>> = rows.iter().map(|r| tensor_of(r, stem)).collect();
        cols.extend(tensor_arrays(&ts));
    }
    if sections.attributes {
        cols.extend(crate::columns::attributes::columns(rows)?);
    }
    if sections.quality {
        cols.extend(crate::columns::quality::QUALITY.arrays(rows)?);
    }
    if sections.signature {
        cols.extend(crate::columns::signature::SIGNATURE.arrays(rows)?);
    }
    if sections.renders {
        cols.extend(crate::columns::renders::RENDERS.arrays(rows)?);
    }
    for name in provenance {
        cols.push(strs(&|r| r.provenance.get(name).map(String::as_str)));
    }
    Ok(RecordBatch::try_new(
        schema_for(provenance, sections),
        cols,
    )?)
}

fn opt_str(a: &StringArray, i: usize) -> Option<String> {
    a.is_valid(i).then(|| a.value(i).to_string())
}

fn opt_u64(a: &UInt64Array, i: usize) -> Option<u64> {
    a.is_valid(i).then(|| a.value(i))
}

fn opt_f64(a: &Float64Array, i: usize) -> Option<f64> {
    a.is_valid(i).then(|| a.value(i))
}

fn parse_stages(s: &str) -> Vec<(String, f64)> {
    match serde_json::from_str::<serde_json::Value>(s) {
        Ok(serde_json::Value::Object(m)) => m
            .into_iter()
            .map(|(k, v)| (k, v.as_f64().unwrap_or(0.0)))
            .collect(),
        _ => Vec::new(),
    }
}

/// The provenance columns of a batch: (manifest column name, its `manifest.<name>` array).
fn provenance_columns(batch: &RecordBatch) -> Result<Vec<(String, &StringArray)>> {
    let schema = batch.schema();
    schema
        .fields()
        .iter()
        .filter_map(|f| Some((f.name(), f.name().strip_prefix(c::PROVENANCE_PREFIX)?)))
        .map(|(column, name)| Ok((name.to_string(), col::<StringArray>(batch, column)?)))
        .collect()
}

/// The normalization of row `i` from the `center_x`, `center_y`, `center_z`, `scale` columns
/// (in that order); `None` when any is null.
fn normalization_at(norm: &[&Float64Array], i: usize) -> Option<Normalization> {
    match (
        opt_f64(norm[0], i),
        opt_f64(norm[1], i),
        opt_f64(norm[2], i),
        opt_f64(norm[3], i),
    ) {
        (Some(x), Some(y), Some(z), Some(s)) => Some(Normalization {
            center: [x, y, z],
            scale: s,
        }),
        _ => None,
    }
}

fn normalization_columns(batch: &RecordBatch) -> Result<Vec<&Float64Array>> {
    [c::CENTER_X, c::CENTER_Y, c::CENTER_Z, c::SCALE]
        .iter()
        .map(|n| col::<Float64Array>(batch, n))
        .collect()
}

/// The four cube tensors of row `i` (without the optional mesh tensors); `None` unless all
/// four are present.
fn cube_tensors_at(batch: &RecordBatch, i: usize) -> Result<Option<RowTensors>> {
    let tensor = |stem| read_tensor(batch, stem, i);
    Ok(
        match (
            tensor("coords")?,
            tensor("sdf")?,
            tensor("deformation")?,
            tensor("cells")?,
        ) {
            (Some(coords), Some(sdf), Some(deformation), Some(cells)) => Some(RowTensors {
                coords,
                sdf,
                deformation,
                cells,
                mesh_vertices: None,
                mesh_faces: None,
                samples: None,
                attributes: None,
                renders: None,
            }),
            _ => None,
        },
    )
}

/// Decodes the id and the sparse cubes of every row of a batch that has at least the columns
/// `id`, `resolution`, `center_x`, `center_y`, `center_z`, `scale` and the `coords`, `sdf`,
/// `deformation` and `cells` tensors: a shard, or a tensor file (docs/FORMAT.md, "Tensor
/// files"). A row without tensors (a failed item) or with inconsistent ones gives an error in
/// its place.
pub fn batch_to_cubes(batch: &RecordBatch) -> Result<Vec<(String, Result<SparseCubes>)>> {
    let id = col::<StringArray>(batch, c::ID)?;
    let resolution = col::<UInt32Array>(batch, c::RESOLUTION)?;
    let norm = normalization_columns(batch)?;
    let mut out = Vec::with_capacity(batch.num_rows());
    for i in 0..batch.num_rows() {
        let cubes = match (cube_tensors_at(batch, i)?, normalization_at(&norm, i)) {
            (Some(t), Some(n)) => t.to_cubes(resolution.value(i), n),
            _ => Err(SchemaError::Invalid {
                what: "row",
                value: format!("item {} has no tensors", id.value(i)),
            }),
        };
        out.push((id.value(i).to_string(), cubes));
    }
    Ok(out)
}

/// Decodes every row of a record batch written with [`schema`].
pub fn batch_to_rows(batch: &RecordBatch) -> Result<Vec<ShardRow>> {
    let index = col::<UInt64Array>(batch, c::ITEM_INDEX)?;
    let id = col::<StringArray>(batch, c::ID)?;
    let uri = col::<StringArray>(batch, c::URI)?;
    let sha = col::<StringArray>(batch, c::SOURCE_SHA256)?;
    let status = col::<StringArray>(batch, c::STATUS)?;
    let class = col::<StringArray>(batch, c::ERROR_CLASS)?;
    let message = col::<StringArray>(batch, c::ERROR_MESSAGE)?;
    let stderr = col::<StringArray>(batch, c::STDERR_TAIL)?;
    let attempts = col::<UInt32Array>(batch, c::ATTEMPTS)?;
    let resolution = col::<UInt32Array>(batch, c::RESOLUTION)?;
    let norm = normalization_columns(batch)?;
    let counts: Vec<&UInt64Array> = COUNT_COLUMNS
        .iter()
        .map(|n| col::<UInt64Array>(batch, n))
        .collect::<Result<_>>()?;
    let times: Vec<&Float64Array> = TIME_COLUMNS
        .iter()
        .map(|n| col::<Float64Array>(batch, n))
        .collect::<Result<_>>()?;
    let stages = col::<StringArray>(batch, c::TIME_STAGES)?;
    let provenance = provenance_columns(batch)?;
    let mut rows = Vec::with_capacity(batch.num_rows());
    for i in 0..batch.num_rows() {
        let normalization = normalization_at(&norm, i);
        let k: Vec<Option<u64>> = counts.iter().map(|a| opt_u64(a, i)).collect();
        let row_counts = match (k[0], k[1], k[3], k[4], k[6], k[7]) {
            (Some(f), Some(v), Some(av), Some(ac), Some(sv), Some(wc)) => Some(RowCounts {
                input_faces: f,
                input_vertices: v,
                input_components: k[2],
                active_vertices: av,
                active_cells: ac,
                output_faces: k[5],
                shell_vertices: sv,
                wall_cells: wc,
            }),
            _ => None,
        };
        let tensors = match cube_tensors_at(batch, i)? {
            Some(t) => Some(RowTensors {
                mesh_vertices: read_tensor(batch, "mesh_vertices", i)?,
                mesh_faces: read_tensor(batch, "mesh_faces", i)?,
                samples: SampleTensors::from_lookup(|stem| read_tensor(batch, stem, i))?,
                attributes: crate::columns::attributes::tensors_at(batch, i)?,
                renders: crate::columns::renders::RENDERS.read(batch, i)?,
                ..t
            }),
            None => None,
        };
        rows.push(ShardRow {
            item_index: index.value(i),
            id: id.value(i).to_string(),
            uri: uri.value(i).to_string(),
            source_sha256: opt_str(sha, i),
            status: ItemStatus::parse(status.value(i))?,
            error_class: opt_str(class, i)
                .map(|s| ErrorClass::parse(&s))
                .transpose()?,
            error_message: opt_str(message, i),
            stderr_tail: opt_str(stderr, i),
            attempts: attempts.value(i),
            resolution: resolution.value(i),
            normalization,
            counts: row_counts,
            timings: RowTimings {
                load_s: times[0].value(i),
                convert_s: times[1].value(i),
                extract_s: times[2].value(i),
                encode_s: times[3].value(i),
                total_s: times[4].value(i),
                stages: parse_stages(stages.value(i)),
            },
            tensors,
            provenance: provenance
                .iter()
                .filter_map(|(name, a)| Some((name.clone(), opt_str(a, i)?)))
                .collect(),
            appearance: crate::columns::attributes::FACTS.read(batch, i)?,
            quality: crate::columns::quality::QUALITY.read(batch, i)?,
            shape_signature: crate::columns::signature::SIGNATURE.read(batch, i)?,
        });
    }
    Ok(rows)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use sparcubes::SparseCubes;

    /// An ok row and a failed row, for tests.
    pub(crate) fn sample_rows() -> Vec<ShardRow> {
        let cubes = SparseCubes {
            resolution: 64,
            normalization: Normalization {
                center: [0.5, -1.0, 2.0],
                scale: 0.25,
            },
            coords: vec![[1, 2, 3], [1, 2, 4]],
            sdf: vec![-0.5, 0.5],
            deformation: vec![[0.1, 0.0, -0.1], [0.0, 0.2, 0.0]],
            cells: vec![[1, 2, 3]],
        };
        let mut tensors = RowTensors::from_cubes(&cubes, 3).unwrap_or_else(|e| panic!("{e}"));
        tensors.mesh_faces = EncodedTensor::from_u32x3(&[[0, 1, 2]], 3).ok();
        let ok = ShardRow {
            item_index: 0,
            id: "a".into(),
            uri: "/x/a.obj".into(),
            source_sha256: Some("ab".into()),
            status: ItemStatus::Ok,
            error_class: None,
            error_message: None,
            stderr_tail: None,
            attempts: 1,
            resolution: 64,
            normalization: Some(cubes.normalization),
            counts: Some(RowCounts {
                input_faces: 12,
                input_vertices: 8,
                input_components: None,
                active_vertices: 2,
                active_cells: 1,
                output_faces: Some(1),
                shell_vertices: 0,
                wall_cells: 1,
            }),
            timings: RowTimings {
                load_s: 0.1,
                convert_s: 0.2,
                extract_s: 0.0,
                encode_s: 0.01,
                total_s: 0.4,
                stages: vec![("band".into(), 0.1)],
            },
            tensors: Some(tensors),
            provenance: Default::default(),
            appearance: None,
            quality: None,
            shape_signature: None,
        };
        let mut failed = ShardRow::failed(
            1,
            "b",
            "/x/b.obj",
            64,
            ErrorClass::Geometry(sparcubes::ErrorClass::ParseError),
            "bad".into(),
        );
        failed.stderr_tail = Some("boom".into());
        vec![ok, failed]
    }

    #[test]
    fn rows_round_trip_through_a_batch() -> Result<()> {
        let rows = sample_rows();
        let batch = rows_to_batch(&rows)?;
        assert_eq!(batch.num_rows(), 2);
        let back = batch_to_rows(&batch)?;
        assert_eq!(back, rows);
        let cubes = back[0].cubes()?;
        assert_eq!(cubes.coords, vec![[1, 2, 3], [1, 2, 4]]);
        assert!(back[1].cubes().is_err());
        Ok(())
    }

    /// [`sample_rows`] with samples in the ok row, drawn by a job whose config draws
    /// `sharp_near` sharp-near points per item, `drawn` of them here (0: no sharp edge).
    fn rows_with_samples(sharp_near: usize, drawn: usize) -> Result<Vec<ShardRow>> {
        let s = sparcubes::samples::Samples {
            surface_points: vec![[0.125, 0.25, 0.5]; 4],
            surface_normals: vec![[0.0, 0.0, 1.0]; 4],
            near_points: vec![[0.5; 3]; 2],
            near_sdf: vec![0.25, -0.5],
            sharp_near_points: vec![[0.25; 3]; drawn],
            sharp_near_sdf: vec![-0.125; drawn],
            volume_points: vec![[1.0; 3]],
            volume_sdf: vec![0.5],
            volume_occupancy: vec![0],
            ..Default::default()
        };
        let params = sparcubes::samples::SampleParams {
            sharp_near,
            ..Default::default()
        };
        let mut rows = sample_rows();
        if let Some(t) = rows[0].tensors.as_mut() {
            t.samples = Some(SampleTensors::from_samples(&s, &params, 3)?);
        }
        Ok(rows)
    }

    #[test]
    fn provenance_columns_follow_the_others_and_read_back() -> Result<()> {
        let mut rows = sample_rows();
        rows[0].provenance.insert("license".into(), "cc0".into());
        let names = ["license".to_string(), "name".to_string()];
        let batch = rows_to_batch_with(&rows, &names)?;
        let schema = batch.schema();
        let last: Vec<&str> = schema
            .fields()
            .iter()
            .rev()
            .take(2)
            .map(|f| f.name().as_str())
            .collect();
        assert_eq!(last, ["manifest.name", "manifest.license"]);
        assert_eq!(schema.fields().len(), super::schema().fields().len() + 2);
        let back = batch_to_rows(&batch)?;
        assert_eq!(back, rows, "a null is no value");
        assert_eq!(rows_to_batch(&sample_rows())?.schema(), super::schema());
        Ok(())
    }

    #[test]
    fn sharp_near_columns_are_stored_when_drawn_and_optional_when_read() -> Result<()> {
        let samples = |rows: &[ShardRow]| rows[0].tensors.as_ref()?.samples.clone();
        for (sharp_near, drawn) in [(3, 3), (3, 0), (0, 0)] {
            let rows = rows_with_samples(sharp_near, drawn)?;
            let stored = samples(&rows).and_then(|s| s.sharp_near);
            assert_eq!(stored.is_some(), sharp_near > 0);
            let batch = rows_to_batch(&rows)?;
            let back = batch_to_rows(&batch)?;
            assert_eq!(back, rows);
            let decoded = samples(&back).map(|s| s.to_samples()).transpose()?;
            assert_eq!(decoded.map(|s| s.sharp_near_points.len()), Some(drawn));
        }
        // A shard written before the kind existed: no sharp-near columns at all. Its rows read
        // with every other sample, and digest as the same rows written now.
        let rows = rows_with_samples(0, 0)?;
        let full = rows_to_batch(&rows)?;
        let schema = full.schema();
        let keep: Vec<usize> = (0..schema.fields().len())
            .filter(|&i| !schema.field(i).name().starts_with("sharp_near"))
            .collect();
        assert_eq!(keep.len(), schema.fields().len() - 6);
        let old = batch_to_rows(&full.project(&keep)?)?;
        assert_eq!(old, rows);
        assert_eq!(
            crate::row::digest::rows_digest(&old),
            crate::row::digest::rows_digest(&rows)
        );
        // Cube columns stay required.
        let no_coords: Vec<usize> = (0..schema.fields().len())
            .filter(|&i| schema.field(i).name() != "coords")
            .collect();
        assert!(batch_to_rows(&full.project(&no_coords)?).is_err());
        Ok(())
    }

    #[test]
    fn cubes_decode_from_the_tensor_columns_alone() -> Result<()> {
        let rows = sample_rows();
        let full = rows_to_batch(&rows)?;
        // A tensor file holds only the id, resolution, normalization and cube tensors.
        let mut keep = vec![c::ID, c::RESOLUTION, c::CENTER_X, c::CENTER_Y, c::CENTER_Z];
        keep.push(c::SCALE);
        let mut names: Vec<String> = keep.iter().map(|s| s.to_string()).collect();
        for t in ["coords", "sdf", "deformation", "cells"] {
            names.extend([t.to_string(), c::dtype_column(t), c::shape_column(t)]);
        }
        let schema = full.schema();
        let indices: Vec<usize> = names
            .iter()
            .map(|n| schema.index_of(n))
            .collect::<std::result::Result<_, _>>()?;
        let subset = full.project(&indices)?;
        let cubes = batch_to_cubes(&subset)?;
        assert_eq!(cubes.len(), 2);
        assert_eq!(cubes[0].0, "a");
        assert_eq!(cubes[0].1.as_ref().ok(), Some(&rows[0].cubes()?));
        assert_eq!(cubes[1].0, "b");
        assert!(cubes[1].1.is_err());
        // A batch without the cube columns is refused as a whole, naming the column.
        let no_cells = full.project(&[schema.index_of(c::ID)?])?;
        let err = batch_to_cubes(&no_cells).err().map(|e| e.to_string());
        assert!(err.is_some_and(|e| e.contains(c::RESOLUTION)));
        Ok(())
    }
}
