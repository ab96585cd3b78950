//! What an export wrote, item by item, and the files that say so: the consumer's listing
//! files and [`RECORD`].

use super::{Staging, RECORD};
use crate::{Consumer, Error, ExportFile, Frame, ItemExport, Listed, Result};
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::path::Path;

/// What became of one item: its files, or why it has none.
#[derive(Debug)]
pub enum Outcome {
    /// The consumer's files of it.
    Files(ItemExport),
    /// The consumer's own pipeline would leave it out, with why (not a failure).
    LeftOut(String),
    /// It failed, with why.
    Failed(String),
}

/// One item on its way to the writer: its names and what became of it.
#[derive(Debug)]
pub struct ItemOutcome {
    /// The item's id.
    pub id: String,
    /// Its file stem.
    pub stem: String,
    /// Its manifest's provenance columns.
    pub provenance: BTreeMap<String, String>,
    /// Its files, or why it has none.
    pub outcome: Outcome,
}

/// What the items' pass wrote.
#[derive(Debug, Default)]
pub struct Written {
    /// The items written, in manifest order.
    pub listed: Vec<Listed>,
    /// The items written with a note of what they lack (Step1X-3D's `sharp_surface`).
    pub noted: Vec<(String, &'static str)>,
    /// The items the consumer's own pipeline would leave out, with why (not failures).
    pub left_out: Vec<(String, String)>,
    /// The items that failed, with why.
    pub failed: Vec<(String, String)>,
    /// Ok items `--where` left out.
    pub filtered_out: u64,
}

impl Written {
    /// Writes one item's files into `staging` and lists it, or counts it as left out, or
    /// as failed.
    pub fn add(&mut self, staging: &Staging, item: ItemOutcome) -> Result<()> {
        match item.outcome {
            Outcome::Files(export) => {
                for f in &export.files {
                    staging.write(f)?;
                }
                if let Some(note) = export.note {
                    self.noted.push((item.id.clone(), note));
                }
                self.listed.push(Listed {
                    id: item.id,
                    stem: item.stem,
                    files: export.files.into_iter().map(|f| f.path).collect(),
                    columns: export.listing,
                    provenance: item.provenance,
                });
            }
            Outcome::LeftOut(why) => self.left_out.push((item.id, why)),
            Outcome::Failed(why) => self.failed.push((item.id, why)),
        }
        Ok(())
    }

    /// The summary's counts after the items written: each note and each reason for leaving
    /// items out with its count ("2 left out: no sharp edges, as Dora's own sampler"), then
    /// the failures; empty when there is none.
    pub fn counts(&self) -> String {
        let mut out = String::new();
        for (note, n) in tally(self.noted.iter().map(|(_, note)| *note)) {
            out.push_str(&format!(", {n} of them {note}"));
        }
        for (why, n) in tally(self.left_out.iter().map(|(_, why)| why.as_str())) {
            out.push_str(&format!(", {n} left out: {why}"));
        }
        if !self.failed.is_empty() {
            out.push_str(&format!(", {} failed", self.failed.len()));
        }
        if self.filtered_out > 0 {
            out.push_str(&format!(", {} left out by --where", self.filtered_out));
        }
        if !(self.noted.is_empty() && self.left_out.is_empty()) {
            out.push_str(&format!(" (ids in {RECORD})"));
        }
        out
    }
}

/// Each distinct text with how many times it comes, in order of the text.
fn tally<'a>(texts: impl Iterator<Item = &'a str>) -> BTreeMap<&'a str, usize> {
    let mut out = BTreeMap::new();
    for t in texts {
        *out.entry(t).or_insert(0) += 1;
    }
    out
}

/// What [`RECORD`] says of the export beside its items: the job, the consumer and frame,
/// and the filter.
#[derive(Debug, Clone, Copy)]
pub struct Record<'a> {
    /// The job's folder.
    pub job: &'a Path,
    /// The job's fingerprint.
    pub fingerprint: &'a str,
    /// The consumer written.
    pub consumer: Consumer,
    /// The frame written.
    pub frame: Frame,
    /// The `--where` filter, as given.
    pub filter: Option<&'a str>,
}

impl Staging {
    /// Writes the consumer's listing files (its `{split}.json`, `metadata.csv`, …; `root` is
    /// where the export ends up, absolute) and then [`RECORD`]: the job, consumer, frame,
    /// and each item's files (and the failures).
    pub fn finish(&self, record: &Record, written: &Written, root: &Path) -> Result<()> {
        for f in record.consumer.listing(&written.listed, root)? {
            self.write(&f)?;
        }
        let bytes = serde_json::to_vec_pretty(&record_json(record, written))
            .map_err(|e| Error::Invalid(format!("writing {RECORD}: {e}")))?;
        self.write(&ExportFile {
            path: RECORD.into(),
            bytes,
        })
    }
}

/// [`RECORD`]'s content.
fn record_json(record: &Record, written: &Written) -> Value {
    let items: Vec<Value> = written
        .listed
        .iter()
        .map(|l| {
            let mut item = json!({
                "id": l.id,
                "stem": l.stem,
                "files": l.files.iter().map(|p| p.to_string_lossy()).collect::<Vec<_>>(),
            });
            if !l.provenance.is_empty() {
                item["manifest"] = json!(l.provenance);
            }
            item
        })
        .collect();
    let listed = |rows: &[(String, String)], key: &str| -> Vec<Value> {
        rows.iter()
            .map(|(id, why)| json!({"id": id, key: why}))
            .collect()
    };
    let noted: Vec<(String, String)> = written
        .noted
        .iter()
        .map(|(id, note)| (id.clone(), note.to_string()))
        .collect();
    let mut out = json!({
        "job": record.job.to_string_lossy(),
        "fingerprint": record.fingerprint,
        "format": record.consumer.name(),
        "frame": record.frame.name(),
        "items": items,
        "noted": listed(&noted, "note"),
        "left_out": listed(&written.left_out, "why"),
        "failed": listed(&written.failed, "error"),
    });
    if let Some(f) = record.filter {
        out["where"] = json!(f);
    }
    out
}
