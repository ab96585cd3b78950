//! The quality columns of a shard: [`QualityFacts`] as Arrow columns and back
//! (docs/FORMAT.md, "Quality columns").

use crate::columns as c;
use crate::columns::table::Kind::{F64, U64};
use crate::columns::table::Role::{Always, Nullable};
use crate::columns::table::{derived, stored, Group, Value};
use crate::row::quality::QualityFacts;
use crate::row::RowCounts;

/// The share of the stored vertices that belong to a thin shell around an open part:
/// `shell_vertices / active_vertices` (0 when nothing is stored).
pub fn shell_share(k: &RowCounts) -> f64 {
    if k.active_vertices == 0 {
        return 0.0;
    }
    k.shell_vertices as f64 / k.active_vertices as f64
}

/// The quality columns, in column order: [`QualityFacts`] and the two columns that follow
/// from them (`aspect`) or from the row's counts (`shell_share`). The digest feeds the ranked
/// columns by rank (`sealed_pockets` among the counts, as it always was) and leaves the derived
/// ones out. The evolution rule is [`crate::columns::table`]'s: a new quality column is one
/// more row at the end, `Role::Added`, over an `Option` field of [`QualityFacts`].
pub static QUALITY: Group<QualityFacts> = Group {
    tag: "quality",
    of: |row| row.quality.as_ref(),
    columns: &[
        stored!(c::INPUT_BOUNDARY_EDGES, U64, Always(0), boundary_edges),
        stored!(
            c::INPUT_NON_MANIFOLD_EDGES,
            U64,
            Always(1),
            non_manifold_edges
        ),
        stored!(c::INPUT_DEGENERATE_FACES, U64, Always(2), degenerate_faces),
        stored!(c::INPUT_DUPLICATE_FACES, U64, Always(3), duplicate_faces),
        stored!(c::EXTENT_X, F64, Always(5), extent[0]),
        stored!(c::EXTENT_Y, F64, Always(6), extent[1]),
        stored!(c::EXTENT_Z, F64, Always(7), extent[2]),
        derived!(c::ASPECT, F64, |_, q| q.aspect().map(Value::F64)),
        stored!(c::SURFACE_AREA, F64, Always(8), surface_area),
        stored!(c::OUTPUT_VOLUME, F64, Nullable(9), output_volume),
        derived!(c::SHELL_SHARE, F64, |r, _| {
            r.counts.as_ref().map(|k| Value::F64(shell_share(k)))
        }),
        stored!(c::SEALED_POCKETS, U64, Always(4), sealed_pockets),
        stored!(c::OUTPUT_COMPONENTS, U64, Nullable(10), output_components),
    ],
};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::columns::arrow::{
        batch_to_rows, rows_to_batch, rows_to_batch_for, schema, Sections,
    };
    use crate::error::Result;
    use crate::row::digest::rows_digest;
    use crate::row::ShardRow;
    use arrow_array::{Array, Float64Array, RecordBatch};

    fn get<'a>(batch: &'a RecordBatch, name: &str) -> Option<&'a Float64Array> {
        batch.column_by_name(name)?.as_any().downcast_ref()
    }

    fn facts() -> QualityFacts {
        QualityFacts {
            boundary_edges: 4,
            non_manifold_edges: 1,
            degenerate_faces: 2,
            duplicate_faces: 3,
            extent: [2.0, 1.0, 0.5],
            surface_area: 7.25,
            output_volume: Some(0.125),
            output_components: Some(2),
            sealed_pockets: 1,
        }
    }

    #[test]
    fn quality_columns_round_trip_and_are_absent_without_the_setting() -> Result<()> {
        let plain = crate::columns::arrow::tests::sample_rows();
        let mut rows = plain.clone();
        rows[0].quality = Some(facts());
        let on = Sections {
            quality: true,
            ..Sections::default()
        };
        let batch = rows_to_batch_for(&rows, &[], on)?;
        assert_eq!(batch.num_columns(), schema().fields().len() + 13);
        let aspect = get(&batch, c::ASPECT).map(|a| (a.value(0), a.is_null(1)));
        assert_eq!(aspect, Some((4.0, true)));
        // sample_rows' ok row stores 2 active vertices, none of them shell.
        let share = get(&batch, c::SHELL_SHARE).map(|a| a.value(0));
        assert_eq!(share, Some(0.0));
        let back = batch_to_rows(&batch)?;
        assert_eq!(back, rows);
        assert_eq!(back[1].quality, None, "the failed row has none");
        assert_ne!(rows_digest(&rows), rows_digest(&plain));
        // Without the setting: the schema, the columns and the digest of before.
        assert_eq!(rows_to_batch(&plain)?.schema(), schema());
        let old = batch_to_rows(&rows_to_batch(&plain)?)?;
        assert_eq!(old, plain);
        Ok(())
    }

    /// The rows with quality facts, written with the quality columns and read back without
    /// the column `dropped`: a shard of an older shape.
    fn read_without(dropped: &str) -> Result<(Vec<ShardRow>, Vec<ShardRow>)> {
        let mut rows = crate::columns::arrow::tests::sample_rows();
        rows[0].quality = Some(facts());
        let on = Sections {
            quality: true,
            ..Sections::default()
        };
        let batch = rows_to_batch_for(&rows, &[], on)?;
        let schema = batch.schema();
        let keep: Vec<usize> = (0..schema.fields().len())
            .filter(|&i| schema.field(i).name() != dropped)
            .collect();
        assert_eq!(
            keep.len(),
            schema.fields().len() - 1,
            "{dropped} is a column"
        );
        Ok((rows, batch_to_rows(&batch.project(&keep)?)?))
    }

    /// A shard lacking a nullable column (`output_volume`) reads with that fact absent and the
    /// rest as written; its digest is that of the rows with the fact absent.
    #[test]
    fn a_shard_without_a_nullable_quality_column_reads_that_fact_as_absent() -> Result<()> {
        let (mut rows, back) = read_without(c::OUTPUT_VOLUME)?;
        if let Some(q) = rows[0].quality.as_mut() {
            q.output_volume = None;
        }
        assert_eq!(back, rows);
        assert_eq!(rows_digest(&back), rows_digest(&rows));
        Ok(())
    }

    /// A shard lacking a founding column (`input_duplicate_faces`) reads as rows without
    /// quality facts, as it always did; so it digests as rows of a job without the columns.
    /// This is why a new column is `Role::Added`, never `Always` (crate::columns::table).
    #[test]
    fn a_shard_without_a_founding_quality_column_reads_without_quality() -> Result<()> {
        let (mut rows, back) = read_without(c::INPUT_DUPLICATE_FACES)?;
        rows[0].quality = None;
        assert_eq!(back, rows);
        assert_eq!(rows_digest(&back), rows_digest(&rows));
        // The derived columns are not read: a shard without them reads as one with them.
        for derived in [c::ASPECT, c::SHELL_SHARE] {
            let (rows, back) = read_without(derived)?;
            assert_eq!(back, rows);
        }
        Ok(())
    }

    #[test]
    fn a_flat_source_has_an_infinite_aspect() {
        let mut q = facts();
        assert_eq!(q.aspect(), Some(4.0));
        q.extent = [3.0, 0.0, 1.0];
        assert_eq!(q.aspect(), Some(f64::INFINITY));
        q.extent = [0.0; 3];
        assert_eq!(q.aspect(), None);
    }
}
