//! Column groups declared once. A group of optional columns (the quality columns, the
//! appearance facts, the shape signature, the render columns) is one [`Group`]: a static table
//! of [`Column`]s in column order, each naming its column, its Arrow type ([`Kind`]), how a
//! row's value is got and put back, and what it is to the content digest ([`Role`]). The Arrow fields
//! ([`Group::fields`]), the arrays over rows ([`Group::arrays`]), the read-back
//! ([`Group::read`]) and the digest's feed (`crate::row::digest`, in [`Group::fed`]'s order)
//! all derive from that one table; nothing else lists the group's columns.
//!
//! # How the schema evolves (the rule, within one [`crate::SCHEMA_VERSION`])
//!
//! - **A new group** of columns comes behind a config key of its own (`quality`,
//!   `shape_signature`, `[attributes]`, `[renders]`) whose absence reads as off, so a job made
//!   before it keeps its fingerprint, resumes writing rows without the group, and its shards
//!   have none of the group's columns ([`crate::columns::arrow::Sections`]). Its digest feed
//!   starts with the group's tag and only rows that have the group feed it, so a row without
//!   it digests as before the group existed.
//! - **A new column in a group** is one more row at the end of the group's table, with the
//!   role [`Role::Added`] and a field of its facts that can say "absent" (an `Option`, or a
//!   list that may be empty). A shard written before it has no such column: its rows read with
//!   that field absent and the rest of the group as it was, by construction ([`Group::read`]
//!   leaves an added column's field at its default). An added column feeds the digest its name
//!   and its value only where the row holds a value, so every row written before it
//!   recomputes the digest it was written with.
//! - **Never** give a new column the role [`Role::Always`]: a shard lacking an `Always` column
//!   reads as rows without the whole group, which would take every older shard's facts (and
//!   change its recomputed digest). The founding columns of each group are pinned by a test
//!   (`founding_columns_are_pinned`).
//! - A change to a column's type, encoding or meaning is a new [`crate::SCHEMA_VERSION`].

use crate::error::{Result, SchemaError};
use crate::row::ShardRow;
use arrow_array::builder::{LargeBinaryBuilder, ListBuilder};
use arrow_array::types::{Float32Type, Float64Type};
use arrow_array::{
    Array, ArrayRef, BooleanArray, FixedSizeListArray, Float32Array, Float64Array,
    LargeBinaryArray, ListArray, RecordBatch, StringArray, UInt32Array, UInt64Array,
};
use arrow_schema::{DataType, Field};
use std::sync::Arc;

/// The Arrow type of a group's column, and so the kind of its values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// `uint32`.
    U32,
    /// `uint64`.
    U64,
    /// `float64`.
    F64,
    /// `bool`.
    Bool,
    /// `utf8`: a list of entries joined by the separator, read back split at it (empty entries
    /// dropped); fed to the digest as the joined text.
    Joined(char),
    /// `fixed_size_list<float32>[n]`.
    F32s(usize),
    /// `utf8`, one text; fed length-prefixed.
    Text,
    /// `utf8`: a list of entries one a line (empty text: no entry); fed entry by entry.
    Lines,
    /// `list<large_binary>`: blobs (PNG files); fed as their count, then each blob.
    Blobs,
    /// `list<float64>`.
    F64s,
}

impl Kind {
    /// The column's Arrow data type.
    fn data_type(self) -> DataType {
        match self {
            Kind::U32 => DataType::UInt32,
            Kind::U64 => DataType::UInt64,
            Kind::F64 => DataType::Float64,
            Kind::Bool => DataType::Boolean,
            Kind::Joined(_) | Kind::Text | Kind::Lines => DataType::Utf8,
            Kind::Blobs => list_of(DataType::LargeBinary),
            Kind::F64s => list_of(DataType::Float64),
            Kind::F32s(n) => {
                let item = Arc::new(Field::new("item", DataType::Float32, true));
                DataType::FixedSizeList(item, n as i32)
            }
        }
    }
}

/// A `list<item>` type whose items are nullable, as Arrow's list builders make them.
fn list_of(item: DataType) -> DataType {
    DataType::List(Arc::new(Field::new("item", item, true)))
}

/// One row's value in a group's column.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// Of a [`Kind::U32`] column.
    U32(u32),
    /// Of a [`Kind::U64`] column.
    U64(u64),
    /// Of a [`Kind::F64`] column.
    F64(f64),
    /// Of a [`Kind::Bool`] column.
    Bool(bool),
    /// Of a [`Kind::Joined`] or [`Kind::Lines`] column.
    Entries(Vec<String>),
    /// Of a [`Kind::F32s`] column.
    F32s(Vec<f32>),
    /// Of a [`Kind::Text`] column.
    Text(String),
    /// Of a [`Kind::Blobs`] column.
    Blobs(Vec<Vec<u8>>),
    /// Of a [`Kind::F64s`] column.
    F64s(Vec<f64>),
}

/// A type a group's facts hold in a column: what it stores, and how it is put back.
pub trait Scalar: Sized {
    /// The value stored for it (`None`: null).
    fn value(&self) -> Option<Value>;
    /// It from a value read back; `None` when the value is of another kind.
    fn from_value(v: Value) -> Option<Self>;
    /// Sets it from a value read back; `None` when the value is of another kind.
    fn put(&mut self, v: Value) -> Option<()> {
        *self = Self::from_value(v)?;
        Some(())
    }
}

macro_rules! scalar {
    ($t:ty, $variant:ident, $store:expr) => {
        impl Scalar for $t {
            fn value(&self) -> Option<Value> {
                Some(Value::$variant($store(self)))
            }
            fn from_value(v: Value) -> Option<Self> {
                match v {
                    Value::$variant(x) => Some(x),
                    _ => None,
                }
            }
        }
    };
}

scalar!(u32, U32, |x: &u32| *x);
scalar!(u64, U64, |x: &u64| *x);
scalar!(f64, F64, |x: &f64| *x);
scalar!(bool, Bool, |x: &bool| *x);
scalar!(Vec<String>, Entries, |x: &Vec<String>| x.clone());
scalar!(Vec<f32>, F32s, |x: &Vec<f32>| x.clone());
scalar!(String, Text, |x: &String| x.clone());
scalar!(Vec<Vec<u8>>, Blobs, |x: &Vec<Vec<u8>>| x.clone());
scalar!(Vec<f64>, F64s, |x: &Vec<f64>| x.clone());

impl<T: Scalar> Scalar for Option<T> {
    fn value(&self) -> Option<Value> {
        self.as_ref().and_then(T::value)
    }
    fn from_value(v: Value) -> Option<Self> {
        T::from_value(v).map(Some)
    }
}

/// What a column is to its group: when its absence takes the group with it, whether it is
/// read back, and how it feeds the content digest.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// A founding column that every row with the group holds: a row (or a shard) without it
    /// reads as a row without the group. Fed as its bare value, `n`-th of the group's ranked
    /// columns (the digest's order, which for historical reasons is not always the column
    /// order).
    Always(u8),
    /// A founding column that may be null where the group is present (a fact not measured):
    /// read back as absent when null or missing; fed `n`-th as a presence byte and the value.
    Nullable(u8),
    /// A column added after the group's first shards (see the module's rule): read back as
    /// absent when null or missing; fed after every ranked column, as its name and its value,
    /// only where the row holds one.
    Added,
    /// A founding column whose value depends on the run (seconds), like the timings: read
    /// back as an [`Role::Always`] column is, never fed.
    Run,
    /// Follows from other columns (or the row): written, neither read back nor fed.
    Derived,
}

/// One column of a group of facts `F`: its name, Arrow type, role, and how a row's value is
/// got (from the row and its facts) and put back (into the facts; `None` for a derived one).
pub struct Column<F: 'static> {
    /// The column's name.
    pub name: &'static str,
    /// Its Arrow type.
    pub kind: Kind,
    /// What it is to the group and to the digest.
    pub role: Role,
    /// The value a row with the facts stores (`None`: null).
    pub get: fn(&ShardRow, &F) -> Option<Value>,
    /// Puts a value read back into the facts (`None` from it: a value of another kind).
    pub set: Option<fn(&mut F, Value) -> Option<()>>,
}

/// A column of a group stored from, and read back into, the field `$($path)+` of its facts.
macro_rules! stored {
    ($name:expr, $kind:expr, $role:expr, $($path:tt)+) => {
        $crate::columns::table::Column {
            name: $name,
            kind: $kind,
            role: $role,
            get: |_, f| $crate::columns::table::Scalar::value(&f.$($path)+),
            set: Some(|f, v| $crate::columns::table::Scalar::put(&mut f.$($path)+, v)),
        }
    };
}
pub(crate) use stored;

/// A derived column of a group: written from `$get` (the row and its facts), never read.
macro_rules! derived {
    ($name:expr, $kind:expr, $get:expr) => {
        $crate::columns::table::Column {
            name: $name,
            kind: $kind,
            role: $crate::columns::table::Role::Derived,
            get: $get,
            set: None,
        }
    };
}
pub(crate) use derived;

/// A group of optional columns, declared once: the facts `F` a row may have, and the table of
/// their columns in column order.
pub struct Group<F: 'static> {
    /// What the digest feeds first for a row with the group.
    pub tag: &'static str,
    /// The row's facts of this group, when it has them.
    pub of: fn(&ShardRow) -> Option<&F>,
    /// The group's columns, in column order.
    pub columns: &'static [Column<F>],
}

impl<F: Default> Group<F> {
    /// The Arrow fields of the group's columns, in column order (all nullable: rows without
    /// the group hold nulls).
    pub fn fields(&self) -> Vec<Field> {
        self.columns
            .iter()
            .map(|c| Field::new(c.name, c.kind.data_type(), true))
            .collect()
    }

    /// The group's arrays over `rows`, in the order of [`Group::fields`]; an error when a
    /// value does not fit its column.
    pub fn arrays(&self, rows: &[ShardRow]) -> Result<Vec<ArrayRef>> {
        self.columns
            .iter()
            .map(|c| {
                let values = rows
                    .iter()
                    .map(|r| (self.of)(r).and_then(|f| (c.get)(r, f)));
                array(c.name, c.kind, values)
            })
            .collect()
    }

    /// The facts of row `i` of `batch`: `None` when the row (or the batch) lacks any of the
    /// group's [`Role::Always`] columns, which is how a shard of a job without the group and a
    /// failed row read; a [`Role::Nullable`] or [`Role::Added`] column that is null or missing
    /// leaves its field at its default (absent). An error when a column has another type.
    pub fn read(&self, batch: &RecordBatch, i: usize) -> Result<Option<F>> {
        let mut facts = F::default();
        for c in self.columns {
            let Some(set) = c.set else { continue };
            let value = match batch.column_by_name(c.name) {
                Some(a) => value_at(a, c.name, c.kind, i)?,
                None => None,
            };
            match (value, c.role) {
                (Some(v), _) => set(&mut facts, v).ok_or_else(|| wrong(c.name, "another kind"))?,
                (None, Role::Always(_) | Role::Run) => return Ok(None),
                (None, _) => {}
            }
        }
        Ok(Some(facts))
    }

    /// The columns the digest feeds, in its order: the ranked ones ([`Role::Always`],
    /// [`Role::Nullable`]) by rank, then the [`Role::Added`] ones in column order.
    pub fn fed(&self) -> Vec<&Column<F>> {
        let mut ranked: Vec<(u8, &Column<F>)> = self
            .columns
            .iter()
            .filter_map(|c| match c.role {
                Role::Always(n) | Role::Nullable(n) => Some((n, c)),
                Role::Added | Role::Run | Role::Derived => None,
            })
            .collect();
        ranked.sort_by_key(|(n, _)| *n);
        let added = self.columns.iter().filter(|c| c.role == Role::Added);
        ranked.into_iter().map(|(_, c)| c).chain(added).collect()
    }
}

fn wrong(name: &str, reason: &str) -> SchemaError {
    SchemaError::Column {
        name: name.into(),
        reason: reason.into(),
    }
}

/// The values of one column as `T`, an error naming the column when one is of another kind.
fn typed<T: Scalar>(
    name: &str,
    values: impl Iterator<Item = Option<Value>>,
) -> Result<Vec<Option<T>>> {
    values
        .map(|v| {
            v.map(|v| T::from_value(v).ok_or_else(|| wrong(name, "a value of another kind")))
                .transpose()
        })
        .collect()
}

/// The array of a column of `kind` over rows' values (`None`: null).
fn array(name: &str, kind: Kind, values: impl Iterator<Item = Option<Value>>) -> Result<ArrayRef> {
    Ok(match kind {
        Kind::U32 => Arc::new(UInt32Array::from(typed::<u32>(name, values)?)),
        Kind::U64 => Arc::new(UInt64Array::from(typed::<u64>(name, values)?)),
        Kind::F64 => Arc::new(Float64Array::from(typed::<f64>(name, values)?)),
        Kind::Bool => Arc::new(BooleanArray::from(typed::<bool>(name, values)?)),
        Kind::Text => Arc::new(StringArray::from(typed::<String>(name, values)?)),
        Kind::Blobs => blobs(typed::<Vec<Vec<u8>>>(name, values)?),
        Kind::F64s => Arc::new(ListArray::from_iter_primitive::<Float64Type, _, _>(
            typed::<Vec<f64>>(name, values)?
                .into_iter()
                .map(|s| s.map(|s| s.into_iter().map(Some).collect::<Vec<_>>())),
        )),
        Kind::Joined(_) | Kind::Lines => {
            let entries = typed::<Vec<String>>(name, values)?;
            let sep = match kind {
                Kind::Joined(sep) => sep.to_string(),
                _ => "\n".to_string(),
            };
            Arc::new(StringArray::from(
                entries
                    .into_iter()
                    .map(|e| e.map(|e| e.join(&sep)))
                    .collect::<Vec<_>>(),
            ))
        }
        Kind::F32s(n) => {
            let lists = typed::<Vec<f32>>(name, values)?;
            if let Some(bad) = lists.iter().flatten().find(|s| s.len() != n) {
                return Err(wrong(name, &format!("{} values, not {n}", bad.len())));
            }
            let values = lists
                .into_iter()
                .map(|s| s.map(|s| s.into_iter().map(Some).collect::<Vec<_>>()));
            Arc::new(FixedSizeListArray::from_iter_primitive::<Float32Type, _, _>(values, n as i32))
        }
    })
}

/// A `list<large_binary>` array over rows' blobs (`None`: null).
fn blobs(rows: Vec<Option<Vec<Vec<u8>>>>) -> ArrayRef {
    let item = Arc::new(Field::new("item", DataType::LargeBinary, true));
    let mut list = ListBuilder::new(LargeBinaryBuilder::new()).with_field(item);
    for row in rows {
        match row {
            Some(blobs) => {
                for b in &blobs {
                    list.values().append_value(b);
                }
                list.append(true);
            }
            None => list.append(false),
        }
    }
    Arc::new(list.finish())
}

/// The array `a` as `T`, an error naming the column when it is of another type.
fn cast<'a, T: 'static>(a: &'a ArrayRef, name: &str) -> Result<&'a T> {
    a.as_any()
        .downcast_ref::<T>()
        .ok_or_else(|| wrong(name, "unexpected type"))
}

/// Row `i`'s value in the column `a` of `kind` (`None`: null).
fn value_at(a: &ArrayRef, name: &str, kind: Kind, i: usize) -> Result<Option<Value>> {
    if !a.is_valid(i) {
        return Ok(None);
    }
    Ok(Some(match kind {
        Kind::U32 => Value::U32(cast::<UInt32Array>(a, name)?.value(i)),
        Kind::U64 => Value::U64(cast::<UInt64Array>(a, name)?.value(i)),
        Kind::F64 => Value::F64(cast::<Float64Array>(a, name)?.value(i)),
        Kind::Bool => Value::Bool(cast::<BooleanArray>(a, name)?.value(i)),
        Kind::Joined(sep) => Value::Entries(
            cast::<StringArray>(a, name)?
                .value(i)
                .split(sep)
                .filter(|p| !p.is_empty())
                .map(str::to_string)
                .collect(),
        ),
        Kind::Text => Value::Text(cast::<StringArray>(a, name)?.value(i).to_string()),
        Kind::Lines => Value::Entries(match cast::<StringArray>(a, name)?.value(i) {
            "" => Vec::new(),
            text => text.split('\n').map(str::to_string).collect(),
        }),
        Kind::Blobs => {
            let items = cast::<ListArray>(a, name)?.value(i);
            let blobs = cast::<LargeBinaryArray>(&items, name)?;
            Value::Blobs(
                blobs
                    .iter()
                    .map(|b| b.unwrap_or_default().to_vec())
                    .collect(),
            )
        }
        Kind::F64s => {
            let items = cast::<ListArray>(a, name)?.value(i);
            Value::F64s(cast::<Float64Array>(&items, name)?.values().to_vec())
        }
        Kind::F32s(n) => {
            let list = cast::<FixedSizeListArray>(a, name)?;
            if list.value_length() != n as i32 {
                let reason = format!("{} values per row, not {n}", list.value_length());
                return Err(wrong(name, &reason));
            }
            let values = list.value(i);
            let floats = cast::<Float32Array>(&values, name)?;
            Value::F32s(floats.values().to_vec())
        }
    }))
}

#[cfg(test)]
mod tests {
    use super::Kind::{F64, U64};
    use super::Role::{Added, Always};
    use super::{Column, Group, Role};
    use crate::columns::attributes::FACTS;
    use crate::columns::quality::QUALITY;
    use crate::columns::renders::RENDERS;
    use crate::columns::signature::SIGNATURE;
    use crate::row::quality::QualityFacts;
    use crate::row::ShardRow;
    use arrow_array::RecordBatch;
    use arrow_schema::Schema;
    use sha2::Digest;
    use std::sync::Arc;

    /// A group's columns by role: (name, rank) of the founding ones, names of the others.
    fn roles<F: Default>(g: &Group<F>) -> (Vec<(&str, u8)>, Vec<&str>) {
        let mut founding = Vec::new();
        let mut others = Vec::new();
        for c in g.columns {
            match c.role {
                Role::Always(n) | Role::Nullable(n) => founding.push((c.name, n)),
                Role::Added | Role::Run | Role::Derived => others.push(c.name),
            }
        }
        (founding, others)
    }

    /// The founding columns of each group, with the rank the digest feeds them at, are those
    /// of the group's first shards: a column added since must be `Role::Added` (or derived),
    /// which this list makes plain when someone adds a founding one by mistake.
    #[test]
    fn founding_columns_are_pinned() {
        let (quality, _) = roles(&QUALITY);
        let q = "input_boundary_edges input_non_manifold_edges input_degenerate_faces \
                 input_duplicate_faces extent_x extent_y extent_z surface_area output_volume \
                 sealed_pockets output_components";
        assert_eq!(quality.iter().map(|c| c.0).collect::<Vec<_>>().join(" "), q);
        let ranks: Vec<u8> = quality.iter().map(|c| c.1).collect();
        assert_eq!(ranks, [0, 1, 2, 3, 5, 6, 7, 8, 9, 4, 10]);
        let (appearance, _) = roles(&FACTS);
        let a = "materials textures texture_max_size alpha_modes vertex_colors \
                 appearance_not_read attribute_nearest_cells";
        assert_eq!(
            appearance.iter().map(|c| c.0).collect::<Vec<_>>().join(" "),
            a
        );
        assert!(appearance
            .iter()
            .enumerate()
            .all(|(i, c)| usize::from(c.1) == i));
        assert_eq!(roles(&SIGNATURE).0, [("shape_signature", 0)]);
        let (renders, others) = roles(&RENDERS);
        assert_eq!(renders, [("render_views", 0), ("render_transforms", 1)]);
        assert_eq!(others, ["render_seconds", "render_not_read"]);
    }

    /// Each group's ranks are 0, 1, … once each, derived columns are not read back and every
    /// other column is.
    #[test]
    fn every_table_is_well_formed() {
        fn check<F: Default>(g: &Group<F>) {
            let mut ranks: Vec<u8> = roles(g).0.iter().map(|c| c.1).collect();
            ranks.sort();
            assert!(
                ranks.iter().enumerate().all(|(i, &n)| usize::from(n) == i),
                "{}",
                g.tag
            );
            for c in g.columns {
                assert_eq!(c.set.is_none(), c.role == Role::Derived, "{}", c.name);
            }
        }
        check(&QUALITY);
        check(&FACTS);
        check(&SIGNATURE);
        check(&RENDERS);
    }

    const EDGES: Column<QualityFacts> = stored!("probe_edges", U64, Always(0), boundary_edges);

    /// A small group over quality facts as its first shards held it (one column), and as it
    /// is once a column is added: one more table row, `Added`, over an `Option` field.
    static FIRST: Group<QualityFacts> = Group {
        tag: "probe",
        of: |row| row.quality.as_ref(),
        columns: &[EDGES],
    };
    static GROWN: Group<QualityFacts> = Group {
        tag: "probe",
        of: |row| row.quality.as_ref(),
        columns: &[EDGES, stored!("probe_volume", F64, Added, output_volume)],
    };

    fn batch(g: &Group<QualityFacts>, rows: &[ShardRow]) -> crate::Result<RecordBatch> {
        let schema = Arc::new(Schema::new(g.fields()));
        Ok(RecordBatch::try_new(schema, g.arrays(rows)?)?)
    }

    fn digest(g: &Group<QualityFacts>, rows: &[ShardRow]) -> Vec<u8> {
        let mut h = sha2::Sha256::new();
        for r in rows {
            crate::row::digest::group(&mut h, g, r);
        }
        h.finalize().to_vec()
    }

    /// What the rule promises, on a group that grows a column: a shard written before the
    /// column reads the new fact as absent and the rest as written, and its rows feed the
    /// digest what they fed before; a row with the new fact feeds it too, and a reader of the
    /// first table reads a newer shard without it.
    #[test]
    fn a_column_added_to_a_group_leaves_older_shards_as_they_were() -> crate::Result<()> {
        let mut rows = crate::columns::arrow::tests::sample_rows();
        let facts = QualityFacts {
            boundary_edges: 7,
            output_volume: Some(0.5),
            ..QualityFacts::default()
        };
        rows[0].quality = Some(facts.clone());
        let older = batch(&FIRST, &rows)?;
        assert_eq!(older.num_columns(), 1);
        let read = GROWN.read(&older, 0)?;
        let absent = QualityFacts {
            output_volume: None,
            ..facts.clone()
        };
        assert_eq!(read, Some(absent.clone()));
        assert_eq!(GROWN.read(&older, 1)?, None, "the failed row has none");
        let mut as_read = rows.clone();
        as_read[0].quality = Some(absent);
        assert_eq!(digest(&GROWN, &as_read), digest(&FIRST, &rows));
        assert_ne!(digest(&GROWN, &rows), digest(&FIRST, &rows));
        let newer = batch(&GROWN, &rows)?;
        assert_eq!(GROWN.read(&newer, 0)?, Some(facts));
        assert_eq!(FIRST.read(&newer, 0)?.map(|q| q.boundary_edges), Some(7));
        Ok(())
    }
}
