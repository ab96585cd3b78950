//! Reading shards back: record batches and rows of a finished shard or a tensor file (its
//! schema version checked), and the rows of a shard whether finished or still in its
//! journals. The facts of a shard file's footer are [`super::footer`]'s.

use super::state::{completion, Check, Completion};
use crate::error::{Result, WorkerError};
use crate::job::Job;
use arrow_array::RecordBatch;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::arrow::ProjectionMask;
use sparc3d_schema::ShardRow;
use std::path::Path;

/// Calls `f` on every record batch of a shard file or a tensor file (docs/FORMAT.md), after
/// checking its schema version: a file of another version is an error that says so.
pub fn for_each_batch<E: From<WorkerError>>(
    path: &Path,
    f: impl FnMut(RecordBatch) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    for_each_batch_of(path, Columns::All, f)
}

/// The columns a read of a shard decodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Columns {
    /// Every column.
    All,
    /// Every column but the sample tensors (their blobs, dtypes and shapes), which are most
    /// of a shard with samples: their rows read as having no samples.
    WithoutSamples,
}

impl Columns {
    /// Whether a read of these columns keeps the column `name`.
    fn keeps(self, name: &str) -> bool {
        match self {
            Columns::All => true,
            Columns::WithoutSamples => !sparc3d_schema::columns::SAMPLE_TENSORS.iter().any(|t| {
                name == *t
                    || name == sparc3d_schema::columns::dtype_column(t)
                    || name == sparc3d_schema::columns::shape_column(t)
            }),
        }
    }
}

/// [`for_each_batch`] reading only `columns`.
pub fn for_each_batch_of<E: From<WorkerError>>(
    path: &Path,
    columns: Columns,
    mut f: impl FnMut(RecordBatch) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    let file =
        std::fs::File::open(path).map_err(|e| WorkerError::read_shard("opening", path, e))?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file)
        .map_err(|e| WorkerError::read_shard("reading", path, e))?;
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
        return Err(WorkerError::BadFile {
            path: path.to_path_buf(),
            reason: format!(
                "shard schema version {}, this sparc3d reads version {expected} \
                 (docs/FORMAT.md); convert the job again with this version",
                version.as_deref().unwrap_or("missing")
            ),
        }
        .into());
    }
    let kept: Vec<usize> = builder
        .schema()
        .fields()
        .iter()
        .enumerate()
        .filter(|(_, field)| columns.keeps(field.name()))
        .map(|(i, _)| i)
        .collect();
    let projection = ProjectionMask::roots(builder.parquet_schema(), kept);
    let reader = builder
        .with_projection(projection)
        .with_batch_size(64)
        .build()
        .map_err(|e| WorkerError::read_shard("reading", path, e))?;
    for batch in reader {
        f(batch.map_err(|e| WorkerError::read_shard("reading", path, e))?)?;
    }
    Ok(())
}

/// The Arrow schema of a shard file (or a tensor file), read from its footer.
pub fn file_schema(path: &Path) -> Result<arrow_schema::SchemaRef> {
    let file =
        std::fs::File::open(path).map_err(|e| WorkerError::read_shard("opening", path, e))?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file)
        .map_err(|e| WorkerError::read_shard("reading", path, e))?;
    Ok(builder.schema().clone())
}

/// Calls `f` on every row of a shard file, batch by batch.
pub fn for_each_row<E: From<WorkerError>>(
    path: &Path,
    f: impl FnMut(ShardRow) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    for_each_row_of(path, Columns::All, f)
}

/// [`for_each_row`] reading only `columns`.
pub fn for_each_row_of<E: From<WorkerError>>(
    path: &Path,
    columns: Columns,
    mut f: impl FnMut(ShardRow) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    for_each_batch_of(path, columns, |batch| {
        let rows = sparc3d_schema::columns::arrow::batch_to_rows(&batch)
            .map_err(|e| WorkerError::read_shard("decoding", path, e))?;
        for row in rows {
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
        Ok::<(), WorkerError>(())
    })?;
    Ok(rows)
}

/// The error for a finished shard that no longer matches its completion record, saying how
/// to get it converted again.
pub fn damaged(job: &Job, shard: u64, why: &str) -> WorkerError {
    WorkerError::Damaged {
        shard,
        root: job.layout.root.clone(),
        why: why.to_string(),
    }
}

/// Rows of a shard whether finished (Parquet, its record checked with `check`) or in progress
/// (its journals), in item order. A damaged shard is an error.
pub fn shard_rows(job: &Job, shard: u64, check: Check) -> Result<Vec<ShardRow>> {
    let mut rows = Vec::new();
    for_each_shard_row(job, shard, check, Columns::All, |row| {
        rows.push(row);
        Ok(())
    })?;
    Ok(rows)
}

/// Calls `f` on each row of a shard, finished or in progress, in item order, reading only
/// `columns`: what [`shard_rows`] returns, without holding the whole shard in memory. With
/// [`Check::Full`] a finished shard's file is hashed on a second thread while its rows are
/// read; a mismatch is an error after the last row, so whatever `f` made of the rows must be
/// discarded when this fails.
pub fn for_each_shard_row(
    job: &Job,
    shard: u64,
    check: Check,
    columns: Columns,
    mut f: impl FnMut(ShardRow) -> Result<()>,
) -> Result<()> {
    let layout = &job.layout;
    let record = match completion(layout, shard, job.fingerprint(), Check::Quick)? {
        Completion::Done(record) => record,
        Completion::Damaged(why) => return Err(damaged(job, shard, &why)),
        Completion::Absent => {
            let state = crate::journal::set::read(layout, shard, None)?;
            for d in state.done.values() {
                f(crate::journal::read_row_at(&d.journal, d.offset)?)?;
            }
            return Ok(());
        }
    };
    let path = layout.shard_file(shard);
    std::thread::scope(|scope| {
        let hashed =
            (check == Check::Full).then(|| scope.spawn(|| crate::fsutil::file_sha256(&path)));
        let read = for_each_row_of(&path, columns, &mut f);
        let Some(hashed) = hashed else {
            return read;
        };
        let sha = hashed.join().unwrap_or_else(|_| {
            Err(WorkerError::io(
                "hashing",
                &path,
                std::io::Error::other("the hashing thread panicked"),
            ))
        })?;
        match super::state::hash_mismatch(&path, &sha, &record) {
            Some(why) => Err(damaged(job, shard, &why)),
            None => read,
        }
    })
}
