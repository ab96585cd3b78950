//! The completion record: written after a shard's rename, it is what makes the shard done.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Written last (`part-NNNNN.complete.json`): a shard without it is not finished.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
    /// Hex content digest of the rows, excluding run-dependent columns.
    pub content_digest: String,
    /// Sum of the items' `time_total_s`.
    pub item_seconds: f64,
    /// Unix time the shard's first item started in the run that finished it.
    pub started_at: f64,
    /// Unix time the record was written.
    pub finished_at: f64,
}
