//! A record batch as a filter's table: what `ls`, `export` and `inspect --where` read a job's
//! rows through. Its scalar columns are the ones a filter may name: strings and booleans as
//! text (`true`/`false`), integers and floats as numbers; tensors (binary and list columns) are
//! not. A provenance column `manifest.<name>` is named by its bare `<name>`, as `init` names it
//! in the manifest, unless the shard has a column of that name itself (then `manifest.<name>`
//! names the provenance one).

use super::{Cell, Kind, Table};
use arrow_array::{
    Array, BooleanArray, Float32Array, Float64Array, Int32Array, Int64Array, LargeStringArray,
    RecordBatch, StringArray, UInt32Array, UInt64Array,
};
use arrow_schema::{DataType, Schema};
use std::borrow::Cow;

/// Prefix of the provenance columns in a shard (`sparc3d_schema::columns::PROVENANCE_PREFIX`).
const PROVENANCE_PREFIX: &str = "manifest.";

/// How a filter compares a column of `data_type`; `None` for columns it cannot name.
fn kind_of(data_type: &DataType) -> Option<Kind> {
    use DataType::*;
    match data_type {
        Utf8 | LargeUtf8 | Boolean => Some(Kind::Text),
        UInt8 | UInt16 | UInt32 | UInt64 | Int8 | Int16 | Int32 | Int64 | Float32 | Float64 => {
            Some(Kind::Number)
        }
        _ => None,
    }
}

/// How a filter compares the field `name` of `schema`: by its type, and none for a tensor's
/// dtype column (`<stem>_dtype` beside a blob column `<stem>`), which is part of the tensor.
fn nameable(schema: &Schema, name: &str) -> Option<Kind> {
    let (_, field) = schema.column_with_name(name)?;
    let tensor_part = name
        .strip_suffix("_dtype")
        .and_then(|stem| schema.column_with_name(stem))
        .is_some_and(|(_, f)| matches!(f.data_type(), DataType::Binary | DataType::LargeBinary));
    (!tensor_part).then(|| kind_of(field.data_type())).flatten()
}

/// The field a filter's column `name` stands for in `schema` (itself, else the provenance
/// column `manifest.<name>`), with its kind; `None` when there is none it may name.
pub fn resolve(schema: &Schema, name: &str) -> Option<(usize, Kind)> {
    let at = |n: &str| Some((schema.index_of(n).ok()?, nameable(schema, n)?));
    at(name).or_else(|| at(&format!("{PROVENANCE_PREFIX}{name}")))
}

/// The columns of `schema` a filter may name, provenance ones by their bare names, in order.
pub fn names(schema: &Schema) -> Vec<String> {
    schema
        .fields()
        .iter()
        .filter(|f| nameable(schema, f.name()).is_some())
        .map(|f| {
            let name = f.name();
            match name.strip_prefix(PROVENANCE_PREFIX) {
                Some(bare) if schema.column_with_name(bare).is_none() => bare.to_string(),
                _ => name.clone(),
            }
        })
        .collect()
}

/// Row `row` of `array` as a cell (null where it is null, or of a type a filter cannot read).
pub fn cell(array: &dyn Array, row: usize) -> Cell<'_> {
    if row >= array.len() || array.is_null(row) {
        return Cell::Null;
    }
    let any = array.as_any();
    let number = |x: f64| Cell::Number(x);
    if let Some(a) = any.downcast_ref::<StringArray>() {
        return Cell::Text(Cow::Borrowed(a.value(row)));
    }
    if let Some(a) = any.downcast_ref::<LargeStringArray>() {
        return Cell::Text(Cow::Borrowed(a.value(row)));
    }
    if let Some(a) = any.downcast_ref::<BooleanArray>() {
        return Cell::Text(Cow::Borrowed(if a.value(row) { "true" } else { "false" }));
    }
    if let Some(a) = any.downcast_ref::<UInt64Array>() {
        return number(a.value(row) as f64);
    }
    if let Some(a) = any.downcast_ref::<UInt32Array>() {
        return number(a.value(row).into());
    }
    if let Some(a) = any.downcast_ref::<Int64Array>() {
        return number(a.value(row) as f64);
    }
    if let Some(a) = any.downcast_ref::<Int32Array>() {
        return number(a.value(row).into());
    }
    if let Some(a) = any.downcast_ref::<Float64Array>() {
        return number(a.value(row));
    }
    if let Some(a) = any.downcast_ref::<Float32Array>() {
        return number(a.value(row).into());
    }
    Cell::Null
}

/// A record batch as a table, named `what` in messages (`the job at …`, a shard's path).
pub struct BatchTable<'a> {
    /// The rows.
    pub batch: &'a RecordBatch,
    /// What the rows are, for messages.
    pub what: String,
}

impl Table for BatchTable<'_> {
    fn what(&self) -> String {
        self.what.clone()
    }

    fn kind(&self, name: &str) -> Option<Kind> {
        resolve(self.batch.schema_ref(), name).map(|(_, k)| k)
    }

    fn names(&self) -> Vec<String> {
        names(self.batch.schema_ref())
    }

    fn cell(&self, row: usize, name: &str) -> Cell<'_> {
        match resolve(self.batch.schema_ref(), name) {
            Some((i, _)) => cell(self.batch.column(i).as_ref(), row),
            None => Cell::Null,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::Filter;
    use super::*;
    use anyhow::Result;
    use arrow_schema::Field;
    use std::sync::Arc;

    /// Four rows: faces, a nullable float, a licence (provenance), a flag, a blob.
    fn batch() -> Result<RecordBatch> {
        use DataType::*;
        let schema = Schema::new(vec![
            Field::new("id", Utf8, false),
            Field::new("input_faces", UInt64, true),
            Field::new("aspect", Float64, true),
            Field::new("resolution", UInt32, false),
            Field::new("textured", Boolean, true),
            Field::new("coords", Binary, true),
            Field::new("coords_dtype", Utf8, true),
            Field::new("manifest.license", Utf8, true),
        ]);
        let columns: Vec<Arc<dyn Array>> = vec![
            Arc::new(StringArray::from(vec!["a", "b", "c", "d"])),
            Arc::new(UInt64Array::from(vec![
                Some(12),
                Some(5000),
                None,
                Some(800),
            ])),
            Arc::new(Float64Array::from(vec![
                Some(1.0),
                Some(f64::INFINITY),
                None,
                Some(2.5),
            ])),
            Arc::new(UInt32Array::from(vec![256, 256, 256, 64])),
            Arc::new(BooleanArray::from(vec![
                Some(true),
                Some(false),
                None,
                None,
            ])),
            Arc::new(arrow_array::BinaryArray::from(vec![
                Some(&b"x"[..]),
                None,
                None,
                None,
            ])),
            Arc::new(StringArray::from(vec![Some("<u2"), None, None, None])),
            Arc::new(StringArray::from(vec![
                Some("cc0"),
                Some("cc-by"),
                None,
                Some("by-nc"),
            ])),
        ];
        Ok(RecordBatch::try_new(Arc::new(schema), columns)?)
    }

    /// The ids of the rows `filter` keeps.
    fn ids(filter: &str) -> Result<Vec<&'static str>> {
        let b = batch()?;
        let t = BatchTable {
            batch: &b,
            what: "the job".into(),
        };
        let f = Filter::parse(filter)?;
        f.check(&t)?;
        let all = ["a", "b", "c", "d"];
        Ok((0..4).filter(|&i| f.keeps(&t, i)).map(|i| all[i]).collect())
    }

    #[test]
    fn numbers_compare_as_numbers_and_nulls_pass_only_the_negations() -> Result<()> {
        assert_eq!(ids("input_faces <= 1000")?, ["a", "d"]);
        assert_eq!(ids("input_faces > 12")?, ["b", "d"]);
        assert_eq!(ids("input_faces >= 12 and input_faces < 800")?, ["a"]);
        assert_eq!(ids("input_faces != 12")?, ["b", "c", "d"]);
        assert_eq!(ids("input_faces not in (12, 800.0)")?, ["b", "c"]);
        assert_eq!(ids("input_faces in (5000, 1e4)")?, ["b"]);
        assert_eq!(ids("resolution = 256.0")?, ["a", "b", "c"]);
        assert_eq!(
            ids("aspect > 2")?,
            ["b", "d"],
            "a flat item's aspect is inf"
        );
        assert_eq!(ids("aspect <= inf")?, ["a", "b", "d"]);
        Ok(())
    }

    #[test]
    fn text_bools_and_provenance_by_bare_name() -> Result<()> {
        assert_eq!(ids("license in (cc0, cc-by)")?, ["a", "b"]);
        assert_eq!(ids("license != cc0")?, ["b", "c", "d"]);
        assert_eq!(ids("manifest.license = by-nc")?, ["d"]);
        assert_eq!(ids("textured = true")?, ["a"]);
        assert_eq!(ids("textured != true")?, ["b", "c", "d"]);
        assert_eq!(
            ids("input_faces <= 1000000 and license in (cc0, cc-by)")?,
            ["a", "b"]
        );
        assert_eq!(
            ids("input_faces <= 1000 and license in (cc0, cc-by)")?,
            ["a"]
        );
        Ok(())
    }

    #[test]
    fn unknown_columns_text_orderings_and_words_on_numbers_are_refused() {
        for (bad, said) in [
            ("licence = cc0", "the job has no column \"licence\""),
            ("coords = x", "no column \"coords\""),
            ("coords_dtype = '<u2'", "no column \"coords_dtype\""),
            ("license < 3", "the column license holds text"),
            (
                "input_faces = many",
                "holds numbers, and \"many\" is not a number",
            ),
            ("input_faces in (1, x)", "\"x\" is not a number"),
        ] {
            let e = ids(bad).err().map(|e| e.to_string()).unwrap_or_default();
            assert!(e.contains(said), "{bad}: {e}");
        }
        let e = ids("licence = cc0")
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            e.contains("(its columns: id, input_faces, aspect, resolution, textured, license)"),
            "{e}"
        );
    }
}
