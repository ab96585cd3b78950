//! Writes a shard while its items convert: each finished row goes into a Parquet file under a
//! temporary name of the writer's own as soon as every item before it is finished (rows stay in
//! item order, row groups close at the same rows, so the file depends on the rows alone, never
//! on the order items finished in); when the last item is finished, the footer, fsync, then the
//! commit ([`super::commit`]): the file linked to the shard's name, fsync of the folder, and
//! the completion record last.

use super::commit::{commit, Committed};
use crate::error::{Result, WorkerError};
use crate::job::Job;
use crate::journal::Journal;
use parquet::arrow::ArrowWriter;
use parquet::basic::{Compression, ZstdLevel};
use parquet::file::metadata::KeyValue;
use parquet::file::properties::{EnabledStatistics, WriterProperties};
use parquet::schema::types::ColumnPath;
use sha2::{Digest, Sha256};
use sparc3d_schema::columns::arrow::Sections;
use sparc3d_schema::{columns, meta_keys, CompletionRecord, FrozenItem, ItemStatus, ShardRow};
use std::collections::{BTreeMap, VecDeque};
use std::fs::File;
use std::path::{Path, PathBuf};

/// Bytes of tensor blobs after which a row group closes (row groups stay well under 256 MB).
const ROW_GROUP_BYTES: usize = 64 << 20;

/// Parquet writer properties of a shard: blobs uncompressed with no dictionary or statistics
/// (they are zstd already), the small columns zstd-compressed.
pub fn writer_properties(job: &Job, shard: u64) -> Result<WriterProperties> {
    let config = job
        .file
        .config
        .to_canonical_json()
        .map_err(WorkerError::Schema)?;
    let kv = vec![
        KeyValue::new(
            meta_keys::SCHEMA_VERSION.into(),
            sparc3d_schema::SCHEMA_VERSION.to_string(),
        ),
        KeyValue::new(meta_keys::CONFIG.into(), config),
        KeyValue::new(meta_keys::FINGERPRINT.into(), job.file.fingerprint.clone()),
        KeyValue::new(
            meta_keys::TOOL_VERSION.into(),
            sparc3d_schema::TOOL_VERSION.to_string(),
        ),
        KeyValue::new(meta_keys::SHARD_INDEX.into(), shard.to_string()),
    ];
    let level = ZstdLevel::try_new(3).map_err(|source| WorkerError::Parquet {
        path: job.layout.shard_file(shard),
        source,
    })?;
    let mut b = WriterProperties::builder()
        .set_compression(Compression::ZSTD(level))
        .set_key_value_metadata(Some(kv));
    for stem in columns::tensors().chain(columns::ATTRIBUTE_TENSORS) {
        let col = ColumnPath::from(stem);
        b = b
            .set_column_compression(col.clone(), Compression::UNCOMPRESSED)
            .set_column_dictionary_enabled(col.clone(), false)
            .set_column_statistics_enabled(col, EnabledStatistics::None);
    }
    Ok(b.build())
}

fn blob_bytes(row: &ShardRow) -> usize {
    row.tensors
        .as_ref()
        .map(|t| {
            t.iter()
                .iter()
                .filter_map(|(_, t)| t.map(|t| t.blob.len()))
                .sum()
        })
        .unwrap_or(0)
}

/// A file writer that hashes what it writes, so the shard is not read back for its sha256.
struct HashingFile {
    file: File,
    hash: Sha256,
}

impl std::io::Write for HashingFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.file.write(buf)?;
        self.hash.update(&buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

/// Writes shard `shard` from its journals (every item must be finished) and commits it,
/// its completion record last: [`ShardStream`] in one go. `writer` names the temporary files
/// (unique per writer); `fence` is called once the file is written, before anything is put in
/// place, and stops a writer that lost its lease.
pub fn write_shard(
    job: &Job,
    shard: u64,
    journal: &Journal,
    writer: &str,
    started_at: f64,
    fence: &dyn Fn() -> Result<()>,
) -> Result<Committed> {
    let mut stream = ShardStream::create(job, shard, writer)?;
    stream.catch_up(journal)?;
    stream.finish(job, shard, started_at, fence)
}

/// What the completion record says of the rows written so far.
#[derive(Default)]
struct Tally {
    digest: Sha256,
    ok: u64,
    failed: u64,
    classes: BTreeMap<String, u64>,
    item_seconds: f64,
}

impl Tally {
    fn count(&mut self, row: &ShardRow) {
        sparc3d_schema::row::digest::update_row(&mut self.digest, row);
        match row.status {
            ItemStatus::Ok => self.ok += 1,
            _ => self.failed += 1,
        }
        if let Some(c) = row.error_class {
            *self.classes.entry(c.as_str().to_string()).or_default() += 1;
        }
        self.item_seconds += row.timings.total_s;
    }
}

/// A shard's Parquet file being written as its items finish, in item order: rows whose
/// earlier items are all finished are written at once ([`ShardStream::catch_up`]), the others
/// wait in the journal. Dropped unfinished (a stop, a lost lease, an error), it removes its
/// temporary file; the journals keep every row.
pub struct ShardStream {
    /// Names this writer's temporary files.
    writer_name: String,
    tmp: PathBuf,
    /// `None` once closed.
    writer: Option<ArrowWriter<HashingFile>>,
    provenance: Vec<String>,
    /// The optional column groups the job's config asks for.
    sections: Sections,
    /// The shard's items not written yet, in row order, with their provenance values.
    waiting: VecDeque<(u64, BTreeMap<String, String>)>,
    /// Blob bytes of the row group being written.
    group_bytes: usize,
    tally: Tally,
}

impl ShardStream {
    /// Opens the temporary file of `writer` (a name unique per writer) for shard `shard`.
    pub fn create(job: &Job, shard: u64, writer: &str) -> Result<Self> {
        let tmp = job.layout.shard_tmp(shard, writer);
        let mut items = job.shard_items(shard)?;
        let provenance = provenance_names(&items);
        let sections = Sections::of(&job.file.config);
        items.sort_unstable_by_key(|i| i.index);
        let waiting = items
            .iter()
            .map(|item| (item.index, item_provenance(item)))
            .collect();
        let file = File::create(&tmp).map_err(|e| WorkerError::io("creating shard", &tmp, e))?;
        let mut stream = Self {
            writer_name: writer.to_string(),
            tmp,
            writer: None,
            provenance,
            sections,
            waiting,
            group_bytes: 0,
            tally: Tally::default(),
        };
        let sink = HashingFile {
            file,
            hash: Sha256::new(),
        };
        let schema = sparc3d_schema::columns::arrow::schema_for(&stream.provenance, sections);
        let properties = writer_properties(job, shard)?;
        let writer = ArrowWriter::try_new(sink, schema, Some(properties))
            .map_err(|e| stream.parquet_error(e))?;
        stream.writer = Some(writer);
        Ok(stream)
    }

    /// Writes every row of `journal` whose earlier items are all finished and that is not
    /// written yet.
    pub fn catch_up(&mut self, journal: &Journal) -> Result<()> {
        while let Some((index, _)) = self.waiting.front() {
            let Some(done) = journal.state.done.get(index) else {
                return Ok(());
            };
            let mut row = journal.read_row(done)?;
            if let Some((_, provenance)) = self.waiting.pop_front() {
                row.provenance = provenance;
            }
            self.push(row)?;
        }
        Ok(())
    }

    /// Writes one row, closing the row group once its blobs reach [`ROW_GROUP_BYTES`].
    fn push(&mut self, row: ShardRow) -> Result<()> {
        self.tally.count(&row);
        self.group_bytes += blob_bytes(&row);
        let batch = sparc3d_schema::columns::arrow::rows_to_batch_for(
            std::slice::from_ref(&row),
            &self.provenance,
            self.sections,
        )?;
        let writer = self.open_writer()?;
        let written = writer.write(&batch);
        written.map_err(|e| self.parquet_error(e))?;
        if self.group_bytes >= ROW_GROUP_BYTES {
            self.group_bytes = 0;
            let flushed = self.open_writer()?.flush();
            flushed.map_err(|e| self.parquet_error(e))?;
        }
        Ok(())
    }

    /// Closes the file once every item is written (its footer, fsync), calls `fence`, and
    /// commits it with its completion record.
    pub fn finish(
        mut self,
        job: &Job,
        shard: u64,
        started_at: f64,
        fence: &dyn Fn() -> Result<()>,
    ) -> Result<Committed> {
        if let Some((index, _)) = self.waiting.front() {
            return Err(WorkerError::BadFile {
                path: self.tmp.clone(),
                reason: format!("item {index} of shard {shard} is not finished"),
            });
        }
        let (file, record) = self.close(job, shard, started_at)?;
        fence()?;
        commit(
            &job.layout,
            shard,
            &job.file.fingerprint,
            &self.tmp,
            &file,
            record,
            &self.writer_name,
        )
    }

    /// The footer written and the file fsynced; the file and its completion record (its size
    /// and stamp are filled in once it is in place).
    fn close(
        &mut self,
        job: &Job,
        shard: u64,
        started_at: f64,
    ) -> Result<(File, CompletionRecord)> {
        let Some(writer) = self.writer.take() else {
            return Err(closed_error(&self.tmp));
        };
        let closed = writer.into_inner();
        let HashingFile { file, hash } = closed.map_err(|e| self.parquet_error(e))?;
        file.sync_all()
            .map_err(|e| WorkerError::io("syncing shard", &self.tmp, e))?;
        let tally = std::mem::take(&mut self.tally);
        let record = CompletionRecord {
            shard,
            schema_version: sparc3d_schema::SCHEMA_VERSION,
            fingerprint: job.file.fingerprint.clone(),
            rows: tally.ok + tally.failed,
            ok: tally.ok,
            failed: tally.failed,
            error_classes: tally.classes,
            bytes: 0,
            sha256: sparc3d_schema::job::config::hex(&hash.finalize()),
            stamp: None,
            object: None,
            object_etag: None,
            content_digest: sparc3d_schema::job::config::hex(&tally.digest.finalize()),
            item_seconds: tally.item_seconds,
            started_at,
            finished_at: 0.0,
        };
        Ok((file, record))
    }

    /// The Parquet writer, while the file is open.
    fn open_writer(&mut self) -> Result<&mut ArrowWriter<HashingFile>> {
        let tmp = &self.tmp;
        self.writer.as_mut().ok_or_else(|| closed_error(tmp))
    }

    fn parquet_error(&self, source: parquet::errors::ParquetError) -> WorkerError {
        WorkerError::Parquet {
            path: self.tmp.clone(),
            source,
        }
    }
}

/// The error of a use of a shard file after it was closed (or failed to open).
fn closed_error(tmp: &Path) -> WorkerError {
    WorkerError::BadFile {
        path: tmp.to_path_buf(),
        reason: "the shard file is closed already".into(),
    }
}

impl Drop for ShardStream {
    /// A stream dropped before its commit leaves no temporary file (a committed one's is gone
    /// already: [`commit`] removes it).
    fn drop(&mut self) {
        self.writer = None;
        let _ = std::fs::remove_file(&self.tmp);
    }
}

/// The provenance columns of a shard: those of its items' manifest lines (every item of one
/// manifest has the same), in name order; none for a manifest without any.
fn provenance_names(items: &[FrozenItem]) -> Vec<String> {
    let names: std::collections::BTreeSet<&String> = items
        .iter()
        .flat_map(|item| item.record.extra.keys())
        .collect();
    names.into_iter().cloned().collect()
}

/// The provenance values of `item` that are not empty (an empty one is stored as null).
fn item_provenance(item: &FrozenItem) -> BTreeMap<String, String> {
    item.record
        .extra
        .iter()
        .filter(|(_, value)| !value.is_empty())
        .map(|(name, value)| (name.clone(), value.clone()))
        .collect()
}
