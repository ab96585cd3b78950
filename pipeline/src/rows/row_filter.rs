//! `--where FILTER` over a job's rows, for `ls`, `export` and `inspect`: the language of `init
//! --where` (`sparc3d_manifests::filter`, one parser for every command), read against the
//! columns a job's shards hold: its provenance columns by their bare names, and every scalar
//! column (counts, quality, appearance facts, status, ...), numbers compared as numbers
//! (docs/FORMAT.md, "Filters on what was measured").
//!
//! A row is judged by its own values: it is written into a one-row batch of the shard's schema
//! (without its tensors, which no filter names) and read through the same table a shard file
//! would be, so the values a filter sees are those the shard stores.

use anyhow::Result;
use arrow_array::RecordBatch;
use arrow_schema::SchemaRef;
use sparc3d_manifests::filter::batch::{resolve, BatchTable};
use sparc3d_manifests::filter::{Cell, Filter, Kind, Table};
use sparc3d_schema::columns::arrow::{rows_to_batch_for, schema_for, Sections};
use sparc3d_schema::{columns as c, FrozenItem, ShardRow};
use sparc3d_workers::Job;
use std::borrow::Cow;
use std::collections::BTreeSet;

/// A parsed filter, checked against the columns of the rows it will judge.
pub struct RowFilter {
    filter: Filter,
    /// The filter as written.
    pub text: String,
    /// The provenance columns of the rows' schema, in order.
    provenance: Vec<String>,
    /// The rows' optional column groups.
    sections: Sections,
    /// The rows' schema.
    schema: SchemaRef,
}

impl RowFilter {
    /// Parses `text` and checks it against the columns `job`'s shards have (its config's
    /// column groups, the provenance columns of all its items).
    pub fn for_job(job: &Job, text: &str) -> Result<Self> {
        // Every item a job gets later carries every column of the earlier ones (`add`), so the
        // last item has them all: one slice read, not the whole manifest.
        let last = match job.file.items.checked_sub(1) {
            Some(i) => job.item(i)?,
            None => None,
        };
        let names: BTreeSet<String> = last
            .map(|i| i.record.extra.into_keys().collect())
            .unwrap_or_default();
        let provenance: Vec<String> = names.into_iter().collect();
        Self::new(text, provenance, Sections::of(&job.file.config), "the job")
    }

    /// [`RowFilter::for_job`] of `--where`'s text when it was given.
    pub fn optional(job: &Job, text: Option<&str>) -> Result<Option<Self>> {
        text.map(|t| Self::for_job(job, t)).transpose()
    }

    /// Parses `text` and checks it against a shard file's own `schema` (`inspect FILE`).
    pub fn for_schema(schema: &arrow_schema::Schema, text: &str, what: &str) -> Result<Self> {
        let provenance = schema
            .fields()
            .iter()
            .filter_map(|f| f.name().strip_prefix(c::PROVENANCE_PREFIX))
            .map(str::to_string)
            .collect();
        let sections = Sections {
            attributes: schema.column_with_name(c::MATERIALS).is_some(),
            quality: schema.column_with_name(c::INPUT_BOUNDARY_EDGES).is_some(),
            signature: schema.column_with_name(c::SHAPE_SIGNATURE).is_some(),
            renders: schema.column_with_name(c::RENDER_VIEWS).is_some(),
        };
        Self::new(text, provenance, sections, what)
    }

    fn new(text: &str, provenance: Vec<String>, sections: Sections, what: &str) -> Result<Self> {
        let filter = Filter::parse(text)?;
        let schema = schema_for(&provenance, sections);
        let empty = RecordBatch::new_empty(schema.clone());
        filter.check(&BatchTable {
            batch: &empty,
            what: what.to_string(),
        })?;
        Ok(Self {
            filter,
            text: text.to_string(),
            provenance,
            sections,
            schema,
        })
    }

    /// Whether `row` passes. Its tensors are set aside while it is judged (and put back);
    /// `item`, when given, supplies its provenance values from the frozen manifest (a
    /// journaled row has none yet).
    pub fn keeps(
        &self,
        row: &mut ShardRow,
        item: Option<&FrozenItem>,
    ) -> sparc3d_schema::Result<bool> {
        let tensors = row.tensors.take();
        let own = item.map(|i| std::mem::replace(&mut row.provenance, provided(i)));
        let batch = rows_to_batch_for(std::slice::from_ref(row), &self.provenance, self.sections);
        row.tensors = tensors;
        if let Some(own) = own {
            row.provenance = own;
        }
        let batch = batch?;
        let table = BatchTable {
            batch: &batch,
            what: String::new(),
        };
        Ok(self.filter.keeps(&table, 0))
    }

    /// Whether an item without a row yet (pending) passes: its index, id, uri and provenance
    /// are known, every other column is null.
    pub fn keeps_pending(&self, item: &FrozenItem) -> bool {
        self.filter.keeps(
            &Pending {
                item,
                schema: &self.schema,
            },
            0,
        )
    }
}

/// An item's provenance values that are not empty (an empty one is stored as null).
fn provided(item: &FrozenItem) -> std::collections::BTreeMap<String, String> {
    let extra = item.record.extra.iter();
    extra
        .filter(|(_, v)| !v.is_empty())
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect()
}

/// A pending item as a one-row table of the job's schema.
struct Pending<'a> {
    item: &'a FrozenItem,
    schema: &'a arrow_schema::Schema,
}

impl Table for Pending<'_> {
    fn what(&self) -> String {
        String::new()
    }

    fn kind(&self, name: &str) -> Option<Kind> {
        resolve(self.schema, name).map(|(_, k)| k)
    }

    fn names(&self) -> Vec<String> {
        sparc3d_manifests::filter::batch::names(self.schema)
    }

    fn cell(&self, _row: usize, name: &str) -> Cell<'_> {
        let Some((i, _)) = resolve(self.schema, name) else {
            return Cell::Null;
        };
        let field = self.schema.field(i).name();
        let r = &self.item.record;
        let text = match field.as_str() {
            c::ID => Some(r.id.as_str()),
            c::URI => Some(r.uri.as_str()),
            c::ITEM_INDEX => return Cell::Number(self.item.index as f64),
            f => f
                .strip_prefix(c::PROVENANCE_PREFIX)
                .and_then(|p| r.extra.get(p))
                .map(String::as_str)
                .filter(|v| !v.is_empty()),
        };
        text.map_or(Cell::Null, |t| Cell::Text(Cow::Borrowed(t)))
    }
}
