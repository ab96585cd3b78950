//! The completion record: written after a shard's rename, it is what makes the shard done.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// What the file system says about a file that only a change of the file alters: its
/// modification and status-change times and its inode. A file whose stamp is as recorded has
/// not been written since (the change time cannot be set back from user space, so a byte
/// flipped and the modification time restored still changes the stamp).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileStamp {
    /// Modification time, nanoseconds since the Unix epoch.
    pub modified_ns: i128,
    /// Status-change time (ctime), nanoseconds since the Unix epoch.
    pub changed_ns: i128,
    /// Inode number.
    pub inode: u64,
}

/// Written last (`part-NNNNN.complete.json`): a shard without it is not finished. Its default
/// (zeros and empty names) serves tests that fill in the fields they mean.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CompletionRecord {
    /// Shard index.
    pub shard: u64,
    /// Schema version of the shard file.
    pub schema_version: u32,
    /// Config fingerprint the shard was written with.
    pub fingerprint: String,
    /// Rows in the shard.
    pub rows: u64,
    /// Rows with status `ok`.
    pub ok: u64,
    /// Rows with status `failed`.
    pub failed: u64,
    /// Failed rows per error class.
    pub error_classes: BTreeMap<String, u64>,
    /// Size of the shard file in bytes.
    pub bytes: u64,
    /// Hex sha256 of the shard file.
    pub sha256: String,
    /// The shard file's stamp once in place: while it is unchanged, a quick check trusts the
    /// file without hashing it (absent in records of older versions).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stamp: Option<FileStamp>,
    /// The name, in the shard's folder, of the object holding the shard's data when it is not
    /// `part-NNNNN.parquet`: a job whose home is a bucket uploads each writer's shard under a
    /// name of its own, and the record (created only where none is) names the one that won
    /// (docs/RELIABILITY.md, "Jobs in a bucket"). Absent on disk.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub object: Option<String>,
    /// The ETag of that object (quotes removed) as the store gave it once uploaded, so that a
    /// listing shows, without reading it, whether the object is still the one recorded; in a
    /// local copy of a bucket job's shard, the ETag of the object copied. Absent on disk and
    /// in records of older versions (docs/RELIABILITY.md, "Jobs in a bucket").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub object_etag: Option<String>,
    /// Hex content digest of the rows, excluding run-dependent columns.
    pub content_digest: String,
    /// Sum of the items' `time_total_s`.
    pub item_seconds: f64,
    /// Unix time the shard's first item started in the run that finished it.
    pub started_at: f64,
    /// Unix time the record was written.
    pub finished_at: f64,
}
