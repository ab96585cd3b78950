//! The appearance columns of a shard (only in the shards of a job with `[attributes]`): the
//! four attribute tensors, each as blob, dtype and shape columns like every tensor, and the
//! per-item facts about the source's materials (docs/FORMAT.md, "Attributes").

use crate::columns as c;
use crate::error::Result;
use crate::row::tensor::EncodedTensor;
use crate::row::{AppearanceFacts, AttributeTensors, ShardRow};
use arrow_array::{
    Array, ArrayRef, BooleanArray, RecordBatch, StringArray, UInt32Array, UInt64Array,
};
use arrow_schema::{DataType, Field};
use std::sync::Arc;

/// The appearance columns' fields, in order: the tensor triples, then the facts.
pub fn fields() -> Vec<Field> {
    use DataType::*;
    let mut f = Vec::new();
    for t in c::ATTRIBUTE_TENSORS {
        f.extend(crate::columns::tensors::tensor_fields(t));
    }
    f.extend([
        Field::new(c::MATERIALS, UInt32, true),
        Field::new(c::TEXTURED, Boolean, true),
        Field::new(c::TEXTURES, UInt32, true),
        Field::new(c::TEXTURE_MAX_SIZE, UInt32, true),
        Field::new(c::ALPHA_MODES, Utf8, true),
        Field::new(c::VERTEX_COLORS, Boolean, true),
        Field::new(c::APPEARANCE_NOT_READ, Utf8, true),
        Field::new(c::NEAREST_CELLS, UInt64, true),
    ]);
    f
}

fn tensor_of<'a>(row: &'a ShardRow, stem: &str) -> Option<&'a EncodedTensor> {
    let a = row.tensors.as_ref()?.attributes.as_ref()?;
    a.iter().into_iter().find(|(s, _)| *s == stem)?.1
}

/// The appearance columns of `rows`, in the order of [`fields`].
pub fn columns(rows: &[ShardRow]) -> Vec<ArrayRef> {
    let mut cols = Vec::new();
    for stem in c::ATTRIBUTE_TENSORS {
        let ts: Vec<Option<&EncodedTensor>> = rows.iter().map(|r| tensor_of(r, stem)).collect();
        cols.extend(crate::columns::tensors::tensor_arrays(&ts));
    }
    let facts: Vec<Option<&AppearanceFacts>> = rows.iter().map(|r| r.appearance.as_ref()).collect();
    let u32s = |f: &dyn Fn(&AppearanceFacts) -> u32| -> ArrayRef {
        Arc::new(UInt32Array::from(
            facts.iter().map(|a| a.map(f)).collect::<Vec<_>>(),
        ))
    };
    let bools = |f: &dyn Fn(&AppearanceFacts) -> bool| -> ArrayRef {
        Arc::new(BooleanArray::from(
            facts.iter().map(|a| a.map(f)).collect::<Vec<_>>(),
        ))
    };
    let strs = |f: &dyn Fn(&AppearanceFacts) -> String| -> ArrayRef {
        Arc::new(StringArray::from(
            facts.iter().map(|a| a.map(f)).collect::<Vec<_>>(),
        ))
    };
    cols.extend([
        u32s(&|a| a.materials),
        bools(&|a| a.textures > 0),
        u32s(&|a| a.textures),
        u32s(&|a| a.texture_max_size),
        strs(&|a| a.alpha_modes.join(",")),
        bools(&|a| a.vertex_colors),
        strs(&|a| a.not_read.join("\n")),
        Arc::new(UInt64Array::from(
            facts
                .iter()
                .map(|a| a.map(|a| a.nearest_cells))
                .collect::<Vec<_>>(),
        )),
    ]);
    cols
}

fn get<'a, T: 'static>(batch: &'a RecordBatch, name: &str) -> Option<&'a T> {
    batch.column_by_name(name)?.as_any().downcast_ref::<T>()
}

/// The attribute tensors of row `i` of a batch, `None` when the batch has no such columns or
/// the row none.
pub fn tensors_at(batch: &RecordBatch, i: usize) -> Result<Option<AttributeTensors>> {
    if batch.column_by_name(c::BASE_COLOR).is_none() {
        return Ok(None);
    }
    AttributeTensors::from_lookup(|stem| crate::columns::tensors::read_tensor(batch, stem, i))
}

/// The appearance facts of row `i`, `None` when the batch has no such columns or the row none.
pub fn facts_at(batch: &RecordBatch, i: usize) -> Option<AppearanceFacts> {
    let u32_at = |name: &str| {
        get::<UInt32Array>(batch, name)
            .filter(|a| a.is_valid(i))
            .map(|a| a.value(i))
    };
    let str_at = |name: &str| {
        get::<StringArray>(batch, name)
            .filter(|a| a.is_valid(i))
            .map(|a| a.value(i).to_string())
    };
    let split = |s: String, sep: char| -> Vec<String> {
        s.split(sep)
            .filter(|p| !p.is_empty())
            .map(str::to_string)
            .collect()
    };
    Some(AppearanceFacts {
        materials: u32_at(c::MATERIALS)?,
        textures: u32_at(c::TEXTURES)?,
        texture_max_size: u32_at(c::TEXTURE_MAX_SIZE)?,
        alpha_modes: split(str_at(c::ALPHA_MODES)?, ','),
        vertex_colors: get::<BooleanArray>(batch, c::VERTEX_COLORS)
            .filter(|a| a.is_valid(i))
            .map(|a| a.value(i))?,
        not_read: split(str_at(c::APPEARANCE_NOT_READ)?, '\n'),
        nearest_cells: get::<UInt64Array>(batch, c::NEAREST_CELLS)
            .filter(|a| a.is_valid(i))
            .map(|a| a.value(i))?,
    })
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
