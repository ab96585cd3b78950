//! The quality columns of a shard: [`QualityFacts`] as Arrow columns and back
//! (docs/FORMAT.md, "Quality columns").

use crate::columns as c;
use crate::row::quality::QualityFacts;
use crate::row::{RowCounts, ShardRow};
use arrow_array::{Array, ArrayRef, Float64Array, RecordBatch, UInt64Array};
use arrow_schema::{DataType, Field};
use std::sync::Arc;

/// The share of the stored vertices that belong to a thin shell around an open part:
/// `shell_vertices / active_vertices` (0 when nothing is stored).
pub fn shell_share(k: &RowCounts) -> f64 {
    if k.active_vertices == 0 {
        return 0.0;
    }
    k.shell_vertices as f64 / k.active_vertices as f64
}

/// The quality columns' fields, in order.
pub fn fields() -> Vec<Field> {
    use DataType::*;
    let u64s = [
        c::INPUT_BOUNDARY_EDGES,
        c::INPUT_NON_MANIFOLD_EDGES,
        c::INPUT_DEGENERATE_FACES,
        c::INPUT_DUPLICATE_FACES,
    ];
    let f64s = [
        c::EXTENT_X,
        c::EXTENT_Y,
        c::EXTENT_Z,
        c::ASPECT,
        c::SURFACE_AREA,
        c::OUTPUT_VOLUME,
        c::SHELL_SHARE,
    ];
    let mut f: Vec<Field> = u64s.map(|n| Field::new(n, UInt64, true)).into();
    f.extend(f64s.map(|n| Field::new(n, Float64, true)));
    f.push(Field::new(c::SEALED_POCKETS, UInt64, true));
    f.push(Field::new(c::OUTPUT_COMPONENTS, UInt64, true));
    f
}

/// The quality columns of `rows`, in the order of [`fields`].
pub fn columns(rows: &[ShardRow]) -> Vec<ArrayRef> {
    let u64s = |f: &dyn Fn(&ShardRow, &QualityFacts) -> Option<u64>| -> ArrayRef {
        let v: Vec<Option<u64>> = rows
            .iter()
            .map(|r| r.quality.as_ref().and_then(|q| f(r, q)))
            .collect();
        Arc::new(UInt64Array::from(v))
    };
    let f64s = |f: &dyn Fn(&ShardRow, &QualityFacts) -> Option<f64>| -> ArrayRef {
        let v: Vec<Option<f64>> = rows
            .iter()
            .map(|r| r.quality.as_ref().and_then(|q| f(r, q)))
            .collect();
        Arc::new(Float64Array::from(v))
    };
    vec![
        u64s(&|_, q| Some(q.boundary_edges)),
        u64s(&|_, q| Some(q.non_manifold_edges)),
        u64s(&|_, q| Some(q.degenerate_faces)),
        u64s(&|_, q| Some(q.duplicate_faces)),
        f64s(&|_, q| Some(q.extent[0])),
        f64s(&|_, q| Some(q.extent[1])),
        f64s(&|_, q| Some(q.extent[2])),
        f64s(&|_, q| q.aspect()),
        f64s(&|_, q| Some(q.surface_area)),
        f64s(&|_, q| q.output_volume),
        f64s(&|r, _| r.counts.as_ref().map(shell_share)),
        u64s(&|_, q| Some(q.sealed_pockets)),
        u64s(&|_, q| q.output_components),
    ]
}

fn get<'a, T: 'static>(batch: &'a RecordBatch, name: &str) -> Option<&'a T> {
    batch.column_by_name(name)?.as_any().downcast_ref::<T>()
}

/// The quality facts of row `i`, `None` when the batch has no such columns (a shard of a job
/// without them) or the row none (a failed row). The derived columns (`aspect`,
/// `shell_share`) are not read: they follow from the others.
pub fn facts_at(batch: &RecordBatch, i: usize) -> Option<QualityFacts> {
    let u = |name: &str| {
        get::<UInt64Array>(batch, name)
            .filter(|a| a.is_valid(i))
            .map(|a| a.value(i))
    };
    let f = |name: &str| {
        get::<Float64Array>(batch, name)
            .filter(|a| a.is_valid(i))
            .map(|a| a.value(i))
    };
    Some(QualityFacts {
        boundary_edges: u(c::INPUT_BOUNDARY_EDGES)?,
        non_manifold_edges: u(c::INPUT_NON_MANIFOLD_EDGES)?,
        degenerate_faces: u(c::INPUT_DEGENERATE_FACES)?,
        duplicate_faces: u(c::INPUT_DUPLICATE_FACES)?,
        extent: [f(c::EXTENT_X)?, f(c::EXTENT_Y)?, f(c::EXTENT_Z)?],
        surface_area: f(c::SURFACE_AREA)?,
        output_volume: f(c::OUTPUT_VOLUME),
        output_components: u(c::OUTPUT_COMPONENTS),
        sealed_pockets: u(c::SEALED_POCKETS)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::columns::arrow::{
        batch_to_rows, rows_to_batch, rows_to_batch_for, schema, Sections,
    };
    use crate::error::Result;
    use crate::row::digest::rows_digest;

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
        let aspect = get::<Float64Array>(&batch, c::ASPECT).map(|a| (a.value(0), a.is_null(1)));
        assert_eq!(aspect, Some((4.0, true)));
        // sample_rows' ok row stores 2 active vertices, none of them shell.
        let share = get::<Float64Array>(&batch, c::SHELL_SHARE).map(|a| a.value(0));
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
