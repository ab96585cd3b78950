//! The `shape_signature` column: each ok row's shape signature
//! (`sparcubes::products::shape_signature`), a fixed-size list of `float32`, null in rows
//! without one (failed items). Only a job with `shape_signature = true` writes it; shards of
//! other jobs (and those written before it) have no such column and read as rows without a
//! signature (docs/FORMAT.md, "Shape signature").

use crate::columns as c;
use crate::error::{Result, SchemaError};
use arrow_array::types::Float32Type;
use arrow_array::{Array, ArrayRef, FixedSizeListArray, Float32Array, RecordBatch};
use arrow_schema::{DataType, Field};
use sparcubes::products::shape_signature::SIGNATURE_LEN;
use std::sync::Arc;

/// The column's field: `fixed_size_list<float32>[SIGNATURE_LEN]`, nullable.
pub fn field() -> Field {
    let item = Arc::new(Field::new("item", DataType::Float32, true));
    Field::new(
        c::SHAPE_SIGNATURE,
        DataType::FixedSizeList(item, SIGNATURE_LEN as i32),
        true,
    )
}

/// The column over rows' signatures (`None`: null in that row). A signature of another length
/// is an error.
pub fn column(signatures: &[Option<&[f32]>]) -> Result<ArrayRef> {
    if let Some(bad) = signatures
        .iter()
        .flatten()
        .find(|s| s.len() != SIGNATURE_LEN)
    {
        return Err(SchemaError::Column {
            name: c::SHAPE_SIGNATURE.into(),
            reason: format!("{} values, not {SIGNATURE_LEN}", bad.len()),
        });
    }
    let values = signatures
        .iter()
        .map(|s| s.map(|s| s.iter().map(|&x| Some(x)).collect::<Vec<_>>()));
    Ok(Arc::new(FixedSizeListArray::from_iter_primitive::<
        Float32Type,
        _,
        _,
    >(values, SIGNATURE_LEN as i32)))
}

/// Every row's signature from a batch, or `None` when the batch has no such column (a shard
/// written before it); an error when the column has another type or length.
pub fn read(batch: &RecordBatch) -> Result<Option<Vec<Option<Vec<f32>>>>> {
    let Some(array) = batch.column_by_name(c::SHAPE_SIGNATURE) else {
        return Ok(None);
    };
    let wrong = |reason: &str| SchemaError::Column {
        name: c::SHAPE_SIGNATURE.into(),
        reason: reason.into(),
    };
    let list = array
        .as_any()
        .downcast_ref::<FixedSizeListArray>()
        .ok_or_else(|| wrong("not a fixed-size list"))?;
    if list.value_length() != SIGNATURE_LEN as i32 {
        return Err(wrong(&format!(
            "{} values per row, not {SIGNATURE_LEN}",
            list.value_length()
        )));
    }
    let mut rows = Vec::with_capacity(list.len());
    for i in 0..list.len() {
        if !list.is_valid(i) {
            rows.push(None);
            continue;
        }
        let value = list.value(i);
        let floats = value
            .as_any()
            .downcast_ref::<Float32Array>()
            .ok_or_else(|| wrong("values are not float32"))?;
        rows.push(Some(floats.values().to_vec()));
    }
    Ok(Some(rows))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::columns::arrow::{
        batch_to_rows, rows_to_batch, rows_to_batch_for, schema, Sections,
    };
    use crate::row::digest::rows_digest;

    #[test]
    fn signatures_round_trip_and_are_absent_without_the_setting() -> Result<()> {
        let plain = crate::columns::arrow::tests::sample_rows();
        let mut rows = plain.clone();
        rows[0].shape_signature = Some((0..32).map(|i| i as f32 / 32.0).collect());
        let on = Sections {
            signature: true,
            ..Sections::default()
        };
        let batch = rows_to_batch_for(&rows, &[], on)?;
        assert_eq!(batch.num_columns(), schema().fields().len() + 1);
        assert_eq!(batch_to_rows(&batch)?, rows);
        let Some(read_back) = read(&batch)? else {
            panic!("no signature column")
        };
        assert_eq!(read_back[0].as_deref(), rows[0].shape_signature.as_deref());
        assert_eq!(read_back[1], None, "the failed row has none");
        assert_ne!(
            rows_digest(&rows),
            rows_digest(&plain),
            "the signature is content"
        );
        // Without the setting (a job stored before the column, or `shape_signature = false`):
        // the schema, the rows and the digest of before.
        let old = rows_to_batch(&plain)?;
        assert_eq!(old.schema(), schema());
        assert!(read(&old)?.is_none());
        assert_eq!(batch_to_rows(&old)?, plain);
        Ok(())
    }

    #[test]
    fn a_signature_of_another_length_is_refused() {
        let short = [0.5f32; 3];
        let err = column(&[Some(&short[..])]).err().map(|e| e.to_string());
        assert!(err.is_some_and(|e| e.contains(c::SHAPE_SIGNATURE)));
    }
}
