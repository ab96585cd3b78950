//! Manifest records: what a job converts. A manifest is read from CSV, JSONL or Parquet; when a
//! job is initialised it is frozen into the job folder with every item's shard.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// One item of a manifest, as given by the user.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ManifestRecord {
    /// Stable id; by default the sha256 of the file's bytes.
    pub id: String,
    /// Path (or URI) of the file.
    pub uri: String,
    /// sha256 of the file's bytes, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sha256: Option<String>,
    /// Format hint (file extension without the dot), when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub format: Option<String>,
    /// The manifest's other columns (provenance: licence, source, name, ...), by lower-case
    /// name; every item of a manifest has every such column, with `""` where its row had no
    /// value. Absent from the frozen line when the manifest had none, so such jobs freeze as
    /// before. Each becomes a `manifest.<name>` string column of the item's shard row
    /// (docs/FORMAT.md, "Provenance columns").
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub extra: BTreeMap<String, String>,
}

/// One item of a frozen manifest (`manifest.jsonl` in the job folder): its position, its
/// shard, and the record. Never changes after `init`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct FrozenItem {
    /// Position in the manifest (0-based); rows are sorted by it.
    pub index: u64,
    /// Shard the item belongs to: `index / shard_size`.
    pub shard: u64,
    /// The record, with `uri` made absolute.
    #[serde(flatten)]
    pub record: ManifestRecord,
}

/// Column names accepted for the path of an item, in order of preference.
pub const PATH_COLUMNS: [&str; 4] = ["uri", "path", "local_path", "file"];
/// Column names accepted for the id of an item, in order of preference.
pub const ID_COLUMNS: [&str; 2] = ["id", "sha256"];
/// The columns a manifest row is read into besides its path column; every other column is
/// kept as provenance ([`ManifestRecord::extra`]).
pub const KNOWN_COLUMNS: [&str; 3] = ["id", "sha256", "format"];
