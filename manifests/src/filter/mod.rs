//! `--where FILTER`: which rows a command takes. `init` chooses a manifest's rows with it when
//! a job is frozen; `ls`, `export` and `inspect` choose a job's rows by what the shards hold
//! (`batch`). A filter is one or more conditions joined by `and`; a condition compares one
//! column (a provenance column, `id`, `uri`, `sha256`, `format`, or a shard's columns) with
//! values:
//!
//! ```text
//! license in (cc-by, cc0)       license = cc0        source != sketchfab
//! license not in ('by-nc', "by-nc-sa") and source = objaverse
//! input_faces <= 1000000 and aspect < 20 and license in (cc0, cc-by)
//! ```
//!
//! Values are bare words (no spaces, commas, parentheses, quotes or `=!<>`) or quoted with `'`
//! or `"` (the grammar: [`parse`]). `=`, `!=`, `in` and `not in` compare as text, except on a
//! numeric column, where both sides are numbers (`resolution = 256` matches `256.0`); `<`, `<=`,
//! `>`, `>=` need a number and a numeric column. A manifest's columns are all text, and a row
//! without a value holds `""`; a shard's column may be null, which satisfies only `!=` and `not
//! in`. A column the table does not have is refused, naming those it has, so a typo never
//! silently selects nothing.

pub mod batch;
pub mod parse;

use crate::table::RawRecord;
use anyhow::{bail, Result};
use parse::{number, Condition, Op};
use std::borrow::Cow;

/// A parsed `--where` filter.
#[derive(Debug, Clone, PartialEq)]
pub struct Filter {
    conditions: Vec<Condition>,
}

/// What a column holds, as a filter compares it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Text (strings, and booleans as `true`/`false`).
    Text,
    /// Numbers (integers and floats).
    Number,
}

/// One row's value in one column.
#[derive(Debug, Clone, PartialEq)]
pub enum Cell<'a> {
    /// No value.
    Null,
    /// A text value.
    Text(Cow<'a, str>),
    /// A number.
    Number(f64),
}

/// What a filter reads: which columns a table has (and of which kind), and its rows' values.
pub trait Table {
    /// What the table is, for messages (`the manifest`, `the job`, a shard's path).
    fn what(&self) -> String;
    /// The kind of column `name` (lower-case, as the filter wrote it), `None` when the table
    /// has no such column.
    fn kind(&self, name: &str) -> Option<Kind>;
    /// The columns a filter may name, in order, for the message that refuses one.
    fn names(&self) -> Vec<String>;
    /// Row `row`'s value in column `name` (one [`Table::kind`] knows).
    fn cell(&self, row: usize, name: &str) -> Cell<'_>;
}

impl Condition {
    /// Refuses a condition `table` cannot answer: a column it lacks, an ordering on a text
    /// column, a value that is not a number on a numeric column.
    fn check(&self, table: &dyn Table) -> Result<()> {
        let Some(kind) = table.kind(&self.column) else {
            bail!(
                "--where: {} has no column {:?} (its columns: {})",
                table.what(),
                self.column,
                table.names().join(", ")
            );
        };
        if kind == Kind::Text && self.op.is_ordering() {
            bail!(
                "--where: `{} {} {}`: the column {} holds text, and `{}` compares numbers",
                self.column,
                self.op.symbol(),
                self.values[0],
                self.column,
                self.op.symbol()
            );
        }
        if let (Kind::Number, Some(v)) = (kind, self.values.iter().find(|v| number(v).is_none())) {
            bail!(
                "--where: the column {} holds numbers, and {v:?} is not a number",
                self.column
            );
        }
        Ok(())
    }

    /// Whether `cell` satisfies the condition (null satisfies only `!=` and `not in`).
    fn holds(&self, cell: &Cell) -> bool {
        match (cell, self.op) {
            (Cell::Null, op) => op == Op::NotIn,
            (Cell::Text(t), op) => self.values.iter().any(|v| v == t) == (op == Op::In),
            (Cell::Number(x), Op::In | Op::NotIn) => {
                let equal = self
                    .values
                    .iter()
                    .filter_map(|v| number(v))
                    .any(|v| v == *x);
                equal == (self.op == Op::In)
            }
            (Cell::Number(x), op) => {
                let Some(v) = self.number else {
                    return false;
                };
                match op {
                    Op::Lt => *x < v,
                    Op::Le => *x <= v,
                    Op::Gt => *x > v,
                    _ => *x >= v,
                }
            }
        }
    }
}

impl Filter {
    /// Parses a filter as the module describes.
    pub fn parse(text: &str) -> Result<Self> {
        Ok(Self {
            conditions: parse::conditions(text)?,
        })
    }

    /// The columns the filter names, in order (lower-case).
    pub fn columns(&self) -> Vec<&str> {
        self.conditions.iter().map(|c| c.column.as_str()).collect()
    }

    /// Refuses a filter `table` cannot answer: a column it lacks (naming those it has), an
    /// ordering on a text column, a value that is not a number on a numeric column.
    pub fn check(&self, table: &dyn Table) -> Result<()> {
        self.conditions.iter().try_for_each(|c| c.check(table))
    }

    /// Whether row `row` of `table` passes every condition (the filter [`Filter::check`]ed
    /// against it).
    pub fn keeps(&self, table: &dyn Table, row: usize) -> bool {
        self.conditions
            .iter()
            .all(|c| c.holds(&table.cell(row, &c.column)))
    }

    /// Whether each of `records` passes (a batch of a manifest's rows: every record of one
    /// manifest has the same columns). A column that the records lack is refused, naming the
    /// manifest's columns.
    pub fn keeps_each(&self, records: &[RawRecord]) -> Result<Vec<bool>> {
        let table = Records(records);
        if !records.is_empty() {
            self.check(&table)?;
        }
        Ok((0..records.len()).map(|i| self.keeps(&table, i)).collect())
    }

    /// The records that pass, in order, and how many were left out. A column that no record
    /// has is refused, naming the manifest's columns.
    pub fn apply(&self, records: Vec<RawRecord>) -> Result<(Vec<RawRecord>, usize)> {
        let keep = self.keeps_each(&records)?;
        let total = records.len();
        let kept: Vec<RawRecord> = records
            .into_iter()
            .zip(keep)
            .filter_map(|(r, k)| k.then_some(r))
            .collect();
        let left_out = total - kept.len();
        Ok((kept, left_out))
    }
}

/// A manifest's records as a table: every column text, `""` where a row has no value; its
/// columns are the first record's.
struct Records<'a>(&'a [RawRecord]);

impl Table for Records<'_> {
    fn what(&self) -> String {
        "the manifest".into()
    }

    fn kind(&self, name: &str) -> Option<Kind> {
        self.0.first()?.column(name).map(|_| Kind::Text)
    }

    fn names(&self) -> Vec<String> {
        let mut names: Vec<String> = ["id", "uri", "sha256", "format"].map(String::from).into();
        if let Some(first) = self.0.first() {
            names.extend(first.extra.keys().cloned());
        }
        names
    }

    fn cell(&self, row: usize, name: &str) -> Cell<'_> {
        // Every record of a manifest has its columns (`""` where it has no value).
        match self.0.get(row).and_then(|r| r.column(name)) {
            Some(v) => Cell::Text(Cow::Borrowed(v)),
            None => Cell::Null,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(license: &str, source: &str) -> RawRecord {
        RawRecord {
            id: Some(format!("{license}-{source}")),
            uri: "/d/a.obj".into(),
            sha256: None,
            format: None,
            extra: [("license", license), ("source", source)]
                .into_iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect(),
        }
    }

    fn ids(filter: &str, records: &[RawRecord]) -> Result<(Vec<String>, usize)> {
        let (kept, left_out) = Filter::parse(filter)?.apply(records.to_vec())?;
        Ok((kept.into_iter().filter_map(|r| r.id).collect(), left_out))
    }

    #[test]
    fn conditions_select_rows_by_their_columns() -> Result<()> {
        let rows = [
            record("cc-by", "a"),
            record("cc0", "b"),
            record("by-nc", "a"),
            record("", "b"),
        ];
        assert_eq!(
            ids("license in (cc-by, cc0)", &rows)?,
            (vec!["cc-by-a".into(), "cc0-b".into()], 2)
        );
        assert_eq!(ids("LICENSE = 'cc0'", &rows)?, (vec!["cc0-b".into()], 3));
        assert_eq!(
            ids("license not in (\"by-nc\", '') and source = a", &rows)?,
            (vec!["cc-by-a".into()], 3)
        );
        assert_eq!(ids("source != a", &rows)?.1, 2);
        assert_eq!(ids("license = ''", &rows)?, (vec!["-b".into()], 3));
        assert_eq!(ids("id = cc0-b", &rows)?.0, vec!["cc0-b".to_string()]);
        Ok(())
    }

    #[test]
    fn bad_filters_and_unknown_columns_are_refused() {
        let rows = [record("cc0", "a")];
        for bad in [
            "license",
            "license in cc0",
            "license in (cc0",
            "license = 'cc0",
            "license = cc0 or source = a",
            "license ! cc0",
            "",
        ] {
            assert!(Filter::parse(bad).is_err(), "{bad}");
        }
        // Issue 41, defect 7: what was found is said in words, never as Rust debug text.
        for (bad, said) in [
            ("type license", "after type, found the word \"license\""),
            (
                "license in (cc0 'by')",
                "expected `,` or `)`, found the quoted value \"by\"",
            ),
            ("license in", "expected `(`, found the end of the filter"),
            ("= cc0", "expected a column name, found `=`"),
            (
                "license = cc0 or x = y",
                "joined by `and`, found the word \"or\"",
            ),
            ("license not (cc0)", "expected `in` after `not`, found `(`"),
        ] {
            let e = Filter::parse(bad)
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default();
            assert!(e.contains(said), "{bad}: {e}");
            assert!(!e.contains("Some(") && !e.contains("Word {"), "{e}");
        }
        let e = ids("licence = cc0", &rows)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            e.contains("no column \"licence\"") && e.contains("license, source"),
            "{e}"
        );
    }
}
