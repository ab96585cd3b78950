//! Reading finished shards and journals back: rows, key-value metadata, column sizes.

use anyhow::{Context, Result};
use arrow_array::RecordBatch;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::file::reader::{FileReader, SerializedFileReader};
use sparc3d_schema::{JobLayout, ShardRow};
use sparc3d_workers::state::{completion, Check, Completion};
use sparc3d_workers::Job;
use std::collections::BTreeMap;
use std::path::Path;

/// Calls `f` on every record batch of a shard file or a tensor file (docs/FORMAT.md), after
/// checking its schema version.
pub fn for_each_batch(path: &Path, mut f: impl FnMut(RecordBatch) -> Result<()>) -> Result<()> {
    let file = std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file)
        .with_context(|| format!("reading {}", path.display()))?;
    let version = builder
        .metadata()
        .file_metadata()
        .key_value_metadata()
        .and_then(|kvs| {
            kvs.iter()
                .find(|k| k.key == sparc3d_schema::meta_keys::SCHEMA_VERSION)
                .and_then(|k| k.value.clone())
        });
    let expected = sparc3d_schema::SCHEMA_VERSION.to_string();
    if version.as_deref() != Some(expected.as_str()) {
        anyhow::bail!(
            "{}: shard schema version {}, this sparc3d reads version {expected} \
             (docs/FORMAT.md); convert the job again with this version",
            path.display(),
            version.as_deref().unwrap_or("missing")
        );
    }
    let reader = builder
        .with_batch_size(64)
        .build()
        .with_context(|| format!("reading {}", path.display()))?;
    for batch in reader {
        f(batch.with_context(|| format!("reading {}", path.display()))?)?;
    }
    Ok(())
}

/// Calls `f` on every row of a shard file, batch by batch.
pub fn for_each_row(path: &Path, mut f: impl FnMut(ShardRow) -> Result<()>) -> Result<()> {
    for_each_batch(path, |batch| {
        for row in sparc3d_schema::arrow::batch_to_rows(&batch)
            .with_context(|| format!("decoding {}", path.display()))?
        {
            f(row)?;
        }
        Ok(())
    })
}

/// Every row of a shard file.
pub fn read_rows(path: &Path) -> Result<Vec<ShardRow>> {
    let mut rows = Vec::new();
    for_each_row(path, |r| {
        rows.push(r);
        Ok(())
    })?;
    Ok(rows)
}

/// Facts from a shard file's footer.
#[derive(Debug, Clone, Default)]
pub struct ShardMeta {
    /// Key-value metadata.
    pub kv: BTreeMap<String, String>,
    /// Rows.
    pub rows: u64,
    /// Row groups.
    pub row_groups: usize,
    /// Stored (compressed) bytes per column, in schema order.
    pub column_bytes: Vec<(String, u64)>,
    /// File size.
    pub file_bytes: u64,
}

/// Reads a shard file's footer.
pub fn read_meta(path: &Path) -> Result<ShardMeta> {
    let file = std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
    let file_bytes = file.metadata().map(|m| m.len()).unwrap_or(0);
    let reader =
        SerializedFileReader::new(file).with_context(|| format!("reading {}", path.display()))?;
    let md = reader.metadata();
    let fmd = md.file_metadata();
    let kv = fmd
        .key_value_metadata()
        .map(|kvs| {
            kvs.iter()
                .map(|k| (k.key.clone(), k.value.clone().unwrap_or_default()))
                .collect()
        })
        .unwrap_or_default();
    let mut column_bytes: Vec<(String, u64)> = Vec::new();
    for rg in md.row_groups() {
        for (i, c) in rg.columns().iter().enumerate() {
            let name = c.column_path().string();
            let bytes = c.compressed_size().max(0) as u64;
            match column_bytes.get_mut(i) {
                Some(slot) => slot.1 += bytes,
                None => column_bytes.push((name, bytes)),
            }
        }
    }
    Ok(ShardMeta {
        kv,
        rows: fmd.num_rows().max(0) as u64,
        row_groups: md.num_row_groups(),
        column_bytes,
        file_bytes,
    })
}

/// The error for a finished shard that no longer matches its completion record, saying how
/// to get it converted again.
pub fn damaged(job: &Job, shard: u64, why: &str) -> anyhow::Error {
    let root = job.layout.root.display();
    anyhow::anyhow!(
        "shard {shard} of {root} is damaged: {why}; `sparc3d verify {root}` moves damaged \
         shards aside and `sparc3d run {root}` converts them again"
    )
}

/// Rows of a shard whether finished (Parquet, its record checked with `check`) or in progress
/// (journal), in item order. A damaged shard is an error.
pub fn shard_rows(job: &Job, shard: u64, check: Check) -> Result<Vec<ShardRow>> {
    let layout: &JobLayout = &job.layout;
    match completion(layout, shard, job.fingerprint(), check)? {
        Completion::Done(_) => return read_rows(&layout.shard_file(shard)),
        Completion::Damaged(why) => return Err(damaged(job, shard, &why)),
        Completion::Absent => {}
    }
    let jpath = layout.journal(shard);
    if !jpath.exists() {
        return Ok(Vec::new());
    }
    let state = sparc3d_workers::journal::replay(&jpath)?;
    state
        .done
        .values()
        .map(|d| Ok(sparc3d_workers::journal::read_row_at(&jpath, d.offset)?))
        .collect()
}
