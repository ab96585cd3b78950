//! The rows a job is made or grown from, a batch at a time: a manifest read with
//! `--path-column` and `--where` (saying which column its paths came from and what `--where`
//! left out), or a folder of meshes scanned as `manifest build` does. A manifest is never held
//! whole: `init` and `add` of ten million rows read it in batches ([`InputRows`]).

use crate::flags::source::SourceArgs;
use anyhow::{bail, Result};
use sparc3d_manifests::filter::Filter;
use sparc3d_manifests::folder_scan::collect;
use sparc3d_manifests::stream::RowStream;
use sparc3d_manifests::RawRecord;
use std::path::{Path, PathBuf};

/// Rows handed on at a time: enough to hash files and serialize items in parallel, few enough
/// to keep memory small (about 40 MB of records).
pub const BATCH_ROWS: usize = 1 << 16;

/// The rows of a folder or manifest, read a batch at a time, those `--where` leaves out left
/// out; rows without a readable source are refused by [`InputRows::finish`] (the stream
/// gathers them).
pub struct InputRows {
    input: PathBuf,
    rows: Rows,
    filter: Option<(String, Filter)>,
    kept: u64,
    left_out: u64,
}

/// Where the rows come from.
enum Rows {
    /// A folder's scan (its records in memory; numbered from 1).
    Scanned(std::iter::Enumerate<std::vec::IntoIter<RawRecord>>),
    /// A manifest, streamed.
    Manifest(Box<RowStream>),
}

impl InputRows {
    /// The rows of `input`: a folder scanned as `manifest build` does, or a manifest read as
    /// `init` reads it (with `--path-column` and `--where`).
    pub fn open(input: &Path, source: &SourceArgs) -> Result<Self> {
        let rows = if input.is_dir() {
            let c = collect(input)?;
            eprintln!(
                "{}: {} meshes ({} identical duplicates left out, {} unreadable, {} skipped)",
                input.display(),
                c.records.len(),
                c.duplicates,
                c.unreadable,
                c.skipped
            );
            let records: Vec<RawRecord> = c.records.into_iter().map(RawRecord::from).collect();
            Rows::Scanned(records.into_iter().enumerate())
        } else {
            Rows::Manifest(Box::new(open_manifest(input, source)?))
        };
        let filter = match &source.filter {
            Some(text) => Some((text.clone(), Filter::parse(text)?)),
            None => None,
        };
        Ok(Self {
            input: input.to_path_buf(),
            rows,
            filter,
            kept: 0,
            left_out: 0,
        })
    }

    /// The next rows that pass `--where`, each with its row number; none at the end.
    pub fn next_batch(&mut self) -> Result<Vec<(u64, RawRecord)>> {
        loop {
            let batch = self.read_batch()?;
            if batch.is_empty() {
                return Ok(batch);
            }
            let batch = self.select(batch)?;
            if !batch.is_empty() {
                return Ok(batch);
            }
        }
    }

    fn read_batch(&mut self) -> Result<Vec<(u64, RawRecord)>> {
        match &mut self.rows {
            Rows::Scanned(records) => Ok(records
                .by_ref()
                .take(BATCH_ROWS)
                .map(|(i, r)| (i as u64 + 1, r))
                .collect()),
            Rows::Manifest(stream) => stream.next_batch(BATCH_ROWS),
        }
    }

    /// The rows of `batch` that pass `--where` (all without it).
    fn select(&mut self, batch: Vec<(u64, RawRecord)>) -> Result<Vec<(u64, RawRecord)>> {
        let Some((_, filter)) = &self.filter else {
            self.kept += batch.len() as u64;
            return Ok(batch);
        };
        let (numbers, records): (Vec<u64>, Vec<RawRecord>) = batch.into_iter().unzip();
        let keep = filter.keeps_each(&records)?;
        let total = keep.len();
        let kept: Vec<(u64, RawRecord)> = numbers
            .into_iter()
            .zip(records)
            .zip(keep)
            .filter_map(|(row, k)| k.then_some(row))
            .collect();
        self.kept += kept.len() as u64;
        self.left_out += (total - kept.len()) as u64;
        Ok(kept)
    }

    /// After the last batch: refuses a manifest that has no rows, no path column, rows
    /// without a readable source, or no row that passes `--where`; says which column the
    /// paths came from, the provenance columns and what `--where` left out.
    pub fn finish(&self) -> Result<()> {
        if let Rows::Manifest(stream) = &self.rows {
            stream.finish()?;
            let column = stream.path_column();
            eprintln!(
                "{}: {} rows, paths from column {} ({})",
                self.input.display(),
                stream.rows_read(),
                column.name,
                column.why
            );
            if !stream.extra_names().is_empty() {
                eprintln!(
                    "{}: provenance columns kept with every item: {}",
                    self.input.display(),
                    stream.extra_names().join(", ")
                );
            }
        }
        let Some((text, _)) = &self.filter else {
            return Ok(());
        };
        eprintln!(
            "{}: --where {text}: {} rows kept, {} left out",
            self.input.display(),
            self.kept,
            self.left_out
        );
        if self.kept == 0 {
            bail!("{}: no row passes --where {text}", self.input.display());
        }
        Ok(())
    }
}

/// The manifest at `path` opened with `--path-column`.
fn open_manifest(path: &Path, source: &SourceArgs) -> Result<RowStream> {
    RowStream::open(path, source.path_column.as_deref())
}
