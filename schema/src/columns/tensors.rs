//! One tensor as three Arrow columns, its blob, dtype and shape (`<stem>`, `<stem>_dtype`,
//! `<stem>_shape`): their fields, their arrays over rows, and one row's tensor read back; and
//! the typed lookup of a column by name that the reads use. Shared by the shard's own tensors
//! (`arrow.rs`) and the appearance columns (`attribute_columns.rs`).

use crate::columns as c;
use crate::error::{Result, SchemaError};
use crate::row::tensor::{DType, EncodedTensor};
use arrow_array::types::Int64Type;
use arrow_array::{Array, ArrayRef, BinaryArray, ListArray, RecordBatch, StringArray};
use arrow_schema::{DataType, Field};
use std::sync::Arc;

/// The Arrow type of a tensor's shape column: a list of `int64` dimensions.
fn shape_type() -> DataType {
    DataType::List(Arc::new(Field::new("item", DataType::Int64, true)))
}

/// The blob, dtype and shape fields of the tensor `stem`.
pub(crate) fn tensor_fields(stem: &str) -> [Field; 3] {
    [
        Field::new(stem, DataType::Binary, true),
        Field::new(c::dtype_column(stem), DataType::Utf8, true),
        Field::new(c::shape_column(stem), shape_type(), true),
    ]
}

/// The blob, dtype and shape arrays of one tensor over rows (`None`: null in that row).
pub(crate) fn tensor_arrays(ts: &[Option<&EncodedTensor>]) -> [ArrayRef; 3] {
    [
        Arc::new(BinaryArray::from_opt_vec(
            ts.iter().map(|t| t.map(|t| t.blob.as_slice())).collect(),
        )),
        Arc::new(StringArray::from(
            ts.iter()
                .map(|t| t.map(|t| t.dtype.as_str()))
                .collect::<Vec<_>>(),
        )),
        Arc::new(ListArray::from_iter_primitive::<Int64Type, _, _>(
            ts.iter()
                .map(|t| t.map(|t| t.shape.iter().map(|&d| Some(d as i64)).collect::<Vec<_>>())),
        )),
    ]
}

/// The column `name` of `batch` as the array type `T`; an error when it is missing or of
/// another type.
pub(crate) fn col<'a, T: 'static>(batch: &'a RecordBatch, name: &str) -> Result<&'a T> {
    batch
        .column_by_name(name)
        .ok_or_else(|| SchemaError::Column {
            name: name.to_string(),
            reason: "missing".into(),
        })?
        .as_any()
        .downcast_ref::<T>()
        .ok_or_else(|| SchemaError::Column {
            name: name.to_string(),
            reason: "unexpected type".into(),
        })
}

/// The tensor `stem` of row `i`; `None` when its blob is null, or when the batch has no such
/// column and the tensor is one of [`c::SAMPLE_TENSORS`] (a read that left the samples out,
/// or a shard written before that kind existed).
pub(crate) fn read_tensor(
    batch: &RecordBatch,
    stem: &str,
    i: usize,
) -> Result<Option<EncodedTensor>> {
    if batch.column_by_name(stem).is_none() && c::SAMPLE_TENSORS.contains(&stem) {
        return Ok(None);
    }
    let blob = col::<BinaryArray>(batch, stem)?;
    if !blob.is_valid(i) {
        return Ok(None);
    }
    let dtype_col = c::dtype_column(stem);
    let dtype = col::<StringArray>(batch, &dtype_col)?;
    let shape_col = c::shape_column(stem);
    let shape = col::<ListArray>(batch, &shape_col)?;
    if !dtype.is_valid(i) || !shape.is_valid(i) {
        return Err(SchemaError::Column {
            name: stem.to_string(),
            reason: format!("row {i} has a blob but no dtype or shape"),
        });
    }
    let dims = shape.value(i);
    let dims = dims
        .as_any()
        .downcast_ref::<arrow_array::Int64Array>()
        .ok_or_else(|| SchemaError::Column {
            name: shape_col.clone(),
            reason: "shape items are not int64".into(),
        })?;
    Ok(Some(EncodedTensor {
        dtype: DType::parse(dtype.value(i))?,
        shape: dims.values().iter().map(|&d| d.max(0) as u64).collect(),
        blob: blob.value(i).to_vec(),
    }))
}
