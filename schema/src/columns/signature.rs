//! The `shape_signature` column: each ok row's shape signature
//! (`sparcubes::products::shape_signature`), a fixed-size list of `float32`, null in rows
//! without one (failed items). Only a job with `shape_signature = true` writes it; shards of
//! other jobs (and those written before it) have no such column and read as rows without a
//! signature (docs/FORMAT.md, "Shape signature").

use crate::columns as c;
use crate::columns::table::Kind::F32s;
use crate::columns::table::Role::Always;
use crate::columns::table::{Column, Group, Scalar};
use sparcubes::products::shape_signature::SIGNATURE_LEN;

/// The signature's one column, `fixed_size_list<float32>[SIGNATURE_LEN]`, nullable; a
/// signature of another length is an error on write and on read. The digest feeds the column's
/// name, then the floats. The evolution rule is [`crate::columns::table`]'s.
pub static SIGNATURE: Group<Vec<f32>> = Group {
    tag: c::SHAPE_SIGNATURE,
    of: |row| row.shape_signature.as_ref(),
    columns: &[Column {
        name: c::SHAPE_SIGNATURE,
        kind: F32s(SIGNATURE_LEN),
        role: Always(0),
        get: |_, s| s.value(),
        set: Some(|s, v| s.put(v)),
    }],
};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::columns::arrow::{
        batch_to_rows, rows_to_batch, rows_to_batch_for, schema, Sections,
    };
    use crate::error::Result;
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
        assert_eq!(SIGNATURE.read(&batch, 0)?, rows[0].shape_signature);
        assert_eq!(SIGNATURE.read(&batch, 1)?, None, "the failed row has none");
        assert_ne!(
            rows_digest(&rows),
            rows_digest(&plain),
            "the signature is content"
        );
        // Without the setting (a job stored before the column, or `shape_signature = false`):
        // the schema, the rows and the digest of before.
        let old = rows_to_batch(&plain)?;
        assert_eq!(old.schema(), schema());
        assert_eq!(SIGNATURE.read(&old, 0)?, None);
        assert_eq!(batch_to_rows(&old)?, plain);
        Ok(())
    }

    #[test]
    fn a_signature_of_another_length_is_refused() {
        let mut rows = crate::columns::arrow::tests::sample_rows();
        rows[0].shape_signature = Some(vec![0.5; 3]);
        let err = SIGNATURE.arrays(&rows).err().map(|e| e.to_string());
        assert!(err.is_some_and(|e| e.contains(c::SHAPE_SIGNATURE)));
    }
}
