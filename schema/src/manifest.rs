//! Manifest records: what a job converts, and the frozen items of a job (`manifest.jsonl` in
//! its folder: every item with its index and shard). `sparc3d-manifests` reads manifests into
//! records and freezes them; shard rows are built from frozen items.

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
