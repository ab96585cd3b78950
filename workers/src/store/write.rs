//! Writes a finished shard: rows from the journals in item order into a Parquet file under a
//! temporary name of the writer's own, fsync, then the commit ([`super::commit`]): the file
//! linked to the shard's name, fsync of the folder, and the completion record last.

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
use sparc3d_schema::{columns, meta_keys, CompletionRecord, ItemStatus, ShardRow};
use std::collections::BTreeMap;
use std::fs::File;
use std::path::Path;

/// Bytes of tensor blobs per row group (row groups stay well under 256 MB).
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
/// its completion record last. `writer` names the temporary files (unique per writer);
/// `fence` is called once the file is written, before anything is put in place, and stops
/// a writer that lost its lease.
pub fn write_shard(
    job: &Job,
    shard: u64,
    journal: &Journal,
    writer: &str,
    started_at: f64,
    fence: &dyn Fn() -> Result<()>,
) -> Result<Committed> {
    let layout = &job.layout;
    let tmp = layout.shard_tmp(shard, writer);
    let written = File::create(&tmp)
        .map_err(|e| WorkerError::io("creating shard", &tmp, e))
        .and_then(|file| write_parquet(job, shard, journal, file, &tmp, started_at))
        .and_then(|written| fence().map(|()| written));
    let (file, record) = match written {
        Ok(w) => w,
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            return Err(e);
        }
    };
    commit(
        layout,
        shard,
        &job.file.fingerprint,
        &tmp,
        &file,
        record,
        writer,
    )
}

/// The provenance columns of a shard: those of its items' manifest lines (every item of one
/// manifest has the same), in name order; none for a manifest without any.
fn provenance_names(job: &Job, shard: u64) -> Vec<String> {
    let names: std::collections::BTreeSet<&String> = job
        .shard_items(shard)
        .iter()
        .flat_map(|item| item.record.extra.keys())
        .collect();
    names.into_iter().cloned().collect()
}

/// The provenance values of item `index` that are not empty (an empty one is stored as null).
fn item_provenance(job: &Job, index: u64) -> BTreeMap<String, String> {
    let Some(item) = job.items.get(index as usize) else {
        return BTreeMap::new();
    };
    item.record
        .extra
        .iter()
        .filter(|(_, value)| !value.is_empty())
        .map(|(name, value)| (name.clone(), value.clone()))
        .collect()
}

/// The rows of the journals into Parquet at `tmp` (through `file`), fsynced; the file and the
/// completion record that will describe it (its size and stamp are filled in once it is in
/// place).
fn write_parquet(
    job: &Job,
    shard: u64,
    journal: &Journal,
    file: File,
    tmp: &Path,
    started_at: f64,
) -> Result<(File, CompletionRecord)> {
    let pq_err = |source| WorkerError::Parquet {
        path: tmp.to_path_buf(),
        source,
    };
    let provenance = provenance_names(job, shard);
    let attributes = job.file.config.attributes.enabled;
    let mut writer = ArrowWriter::try_new(
        HashingFile {
            file,
            hash: Sha256::new(),
        },
        sparc3d_schema::arrow::schema_for(&provenance, attributes),
        Some(writer_properties(job, shard)?),
    )
    .map_err(pq_err)?;
    let mut digest = Sha256::new();
    let (mut ok, mut failed, mut item_seconds) = (0u64, 0u64, 0.0f64);
    let mut classes: BTreeMap<String, u64> = BTreeMap::new();
    let mut pending: Vec<ShardRow> = Vec::new();
    let mut pending_bytes = 0usize;
    let flush = |writer: &mut ArrowWriter<HashingFile>, rows: &mut Vec<ShardRow>| -> Result<()> {
        if rows.is_empty() {
            return Ok(());
        }
        let batch = sparc3d_schema::arrow::rows_to_batch_for(rows, &provenance, attributes)?;
        writer.write(&batch).map_err(pq_err)?;
        writer.flush().map_err(pq_err)?;
        rows.clear();
        Ok(())
    };
    for done in journal.state.done.values() {
        let mut row = journal.read_row(done)?;
        row.provenance = item_provenance(job, row.item_index);
        sparc3d_schema::digest::update_row(&mut digest, &row);
        match row.status {
            ItemStatus::Ok => ok += 1,
            _ => failed += 1,
        }
        if let Some(c) = row.error_class {
            *classes.entry(c.as_str().to_string()).or_default() += 1;
        }
        item_seconds += row.timings.total_s;
        pending_bytes += blob_bytes(&row);
        pending.push(row);
        if pending_bytes >= ROW_GROUP_BYTES {
            flush(&mut writer, &mut pending)?;
            pending_bytes = 0;
        }
    }
    flush(&mut writer, &mut pending)?;
    let HashingFile { file, hash } = writer.into_inner().map_err(pq_err)?;
    let file_sha256 = sparc3d_schema::config::hex(&hash.finalize());
    file.sync_all()
        .map_err(|e| WorkerError::io("syncing shard", tmp, e))?;
    let record = CompletionRecord {
        shard,
        schema_version: sparc3d_schema::SCHEMA_VERSION,
        fingerprint: job.file.fingerprint.clone(),
        rows: ok + failed,
        ok,
        failed,
        error_classes: classes,
        bytes: 0,
        sha256: file_sha256,
        stamp: None,
        object: None,
        object_etag: None,
        content_digest: sparc3d_schema::config::hex(&digest.finalize()),
        item_seconds,
        started_at,
        finished_at: 0.0,
    };
    Ok((file, record))
}
