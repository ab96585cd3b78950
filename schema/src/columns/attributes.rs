//! The appearance columns of a shard (only in the shards of a job with `[attributes]`): the
//! four attribute tensors, each as blob, dtype and shape columns like every tensor, and the
//! per-item facts about the source's materials (docs/FORMAT.md, "Attributes").

use crate::columns as c;
use crate::columns::table::Kind::{Bool, Joined, U32, U64};
use crate::columns::table::Role::Always;
use crate::columns::table::{derived, stored, Group, Value};
use crate::error::Result;
use crate::row::tensor::EncodedTensor;
use crate::row::{AppearanceFacts, AttributeTensors, ShardRow};
use arrow_array::{ArrayRef, RecordBatch};
use arrow_schema::Field;

/// The appearance facts' columns, in column order (after the attribute tensors'); `textured`
/// follows from `textures`. The evolution rule is [`crate::columns::table`]'s.
pub static FACTS: Group<AppearanceFacts> = Group {
    tag: "appearance",
    of: |row| row.appearance.as_ref(),
    columns: &[
        stored!(c::MATERIALS, U32, Always(0), materials),
        derived!(c::TEXTURED, Bool, |_, a| Some(Value::Bool(a.textures > 0))),
        stored!(c::TEXTURES, U32, Always(1), textures),
        stored!(c::TEXTURE_MAX_SIZE, U32, Always(2), texture_max_size),
        stored!(c::ALPHA_MODES, Joined(','), Always(3), alpha_modes),
        stored!(c::VERTEX_COLORS, Bool, Always(4), vertex_colors),
        stored!(c::APPEARANCE_NOT_READ, Joined('\n'), Always(5), not_read),
        stored!(c::NEAREST_CELLS, U64, Always(6), nearest_cells),
    ],
};

/// The appearance columns' fields, in order: the tensor triples, then the facts ([`FACTS`]).
pub fn fields() -> Vec<Field> {
    let mut f = Vec::new();
    for t in c::ATTRIBUTE_TENSORS {
        f.extend(crate::columns::tensors::tensor_fields(t));
    }
    f.extend(FACTS.fields());
    f
}

fn tensor_of<'a>(row: &'a ShardRow, stem: &str) -> Option<&'a EncodedTensor> {
    let a = row.tensors.as_ref()?.attributes.as_ref()?;
    a.iter().into_iter().find(|(s, _)| *s == stem)?.1
}

/// The appearance columns of `rows`, in the order of [`fields`].
pub fn columns(rows: &[ShardRow]) -> Result<Vec<ArrayRef>> {
    let mut cols = Vec::new();
    for stem in c::ATTRIBUTE_TENSORS {
        let ts: Vec<Option<&EncodedTensor>> = rows.iter().map(|r| tensor_of(r, stem)).collect();
        cols.extend(crate::columns::tensors::tensor_arrays(&ts));
    }
    cols.extend(FACTS.arrays(rows)?);
    Ok(cols)
}

/// The attribute tensors of row `i` of a batch, `None` when the batch has no such columns or
/// the row none.
pub fn tensors_at(batch: &RecordBatch, i: usize) -> Result<Option<AttributeTensors>> {
    if batch.column_by_name(c::BASE_COLOR).is_none() {
        return Ok(None);
    }
    AttributeTensors::from_lookup(|stem| crate::columns::tensors::read_tensor(batch, stem, i))
}

#[cfg(test)]
mod tests {
    use crate::columns::arrow::{
        batch_to_rows, rows_to_batch, rows_to_batch_for, schema, schema_for, Sections,
    };
    use crate::error::Result;
    use crate::row::digest::rows_digest;
    use crate::row::{AppearanceFacts, AttributeTensors};
    use sparcubes::attributes::CellAttributes;

    #[test]
    fn attribute_columns_round_trip_and_are_absent_without_the_section() -> Result<()> {
        let plain = crate::columns::arrow::tests::sample_rows();
        // Without `[attributes]`: the schema and the rows' digest are what they always were.
        assert_eq!(schema_for(&[], Sections::default()), schema());
        assert_eq!(rows_to_batch(&plain)?.schema(), schema());
        let mut rows = plain.clone();
        let cells = CellAttributes {
            base_color: vec![[231, 12, 0]],
            metallic: vec![0],
            roughness: vec![128],
            alpha: vec![255],
            nearest_cells: 1,
        };
        let facts = AppearanceFacts {
            materials: 2,
            textures: 1,
            texture_max_size: 512,
            alpha_modes: vec!["MASK".into(), "OPAQUE".into()],
            vertex_colors: false,
            not_read: vec![
                "material 0: normal texture".into(),
                "image 1: PNG: x".into(),
            ],
            nearest_cells: 1,
        };
        if let Some(t) = rows[0].tensors.as_mut() {
            t.attributes = Some(AttributeTensors::from_attributes(&cells, 3)?);
        }
        rows[0].appearance = Some(facts);
        let on = Sections {
            attributes: true,
            ..Sections::default()
        };
        let batch = rows_to_batch_for(&rows, &[], on)?;
        assert_eq!(batch.num_columns(), schema().fields().len() + 12 + 8);
        let back = batch_to_rows(&batch)?;
        assert_eq!(back, rows);
        let decoded = back[0]
            .tensors
            .as_ref()
            .and_then(|t| t.attributes.as_ref())
            .map(AttributeTensors::to_attributes)
            .transpose()?;
        assert_eq!(decoded.map(|a| a.base_color), Some(cells.base_color));
        assert_ne!(rows_digest(&rows), rows_digest(&plain));
        // The failed row has no appearance: nulls, read back as none.
        assert_eq!(back[1].appearance, None);
        Ok(())
    }
}
