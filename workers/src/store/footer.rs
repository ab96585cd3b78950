//! The facts of a shard file's footer (Parquet metadata): its key-value metadata (the config
//! it was written with, its schema version, ...), rows, row groups and the stored bytes per
//! column. It knows no job, so that the check of a job's own files can read a finished
//! shard's config from it.

use crate::error::{Result, WorkerError};
use parquet::file::reader::{FileReader, SerializedFileReader};
use std::collections::BTreeMap;
use std::path::Path;

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
    let file =
        std::fs::File::open(path).map_err(|e| WorkerError::read_shard("opening", path, e))?;
    let file_bytes = file.metadata().map(|m| m.len()).unwrap_or(0);
    let reader =
        SerializedFileReader::new(file).map_err(|e| WorkerError::read_shard("reading", path, e))?;
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
