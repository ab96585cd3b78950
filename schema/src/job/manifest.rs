//! Manifest records: what a job converts, and the frozen items of a job (every item with its
//! index and shard, one JSON line each). A job keeps them in slices, one file per shard, listed
//! with their sha256s by index pages that `job.json` pins ([`ManifestPage`], [`SliceEntry`]); a
//! job made before slices keeps them in one file, `manifest.jsonl`. `sparc3d-manifests` reads
//! manifests into records and freezes them; shard rows are built from frozen items.

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

/// Shards listed by one page of a sliced frozen manifest's index: about 90 KB a page of
/// 256-item shards, so a task reads its page and its slice, never the whole index (at 10 M
/// items, 39 pages).
pub const PAGE_SHARDS: u64 = 1024;

/// One page of a sliced frozen manifest's index, as `job.json` pins it
/// ([`crate::JobFile::manifest_pages`]): page `p` lists shards `p * PAGE_SHARDS ..`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ManifestPage {
    /// Shards the page lists ([`PAGE_SHARDS`] but on the last page).
    pub shards: u64,
    /// Items in those shards.
    pub items: u64,
    /// sha256 of the page file's bytes.
    pub sha256: String,
}

/// One line of an index page: a shard's slice of the frozen manifest.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SliceEntry {
    /// The shard.
    pub shard: u64,
    /// Index of its first item.
    pub first: u64,
    /// Its items.
    pub items: u64,
    /// sha256 of the slice file's bytes (its items' frozen lines).
    pub sha256: String,
}

impl SliceEntry {
    /// The entry as its page line: `shard first items sha256`, tab-separated, with a newline.
    pub fn line(&self) -> String {
        format!(
            "{}\t{}\t{}\t{}\n",
            self.shard, self.first, self.items, self.sha256
        )
    }

    /// Parses a page line (without its newline); `None` when it is not one.
    pub fn parse(line: &str) -> Option<Self> {
        let mut cells = line.split('\t');
        let entry = Self {
            shard: cells.next()?.parse().ok()?,
            first: cells.next()?.parse().ok()?,
            items: cells.next()?.parse().ok()?,
            sha256: cells.next()?.to_string(),
        };
        let hex = entry.sha256.len() == 64 && entry.sha256.bytes().all(|b| b.is_ascii_hexdigit());
        (cells.next().is_none() && hex).then_some(entry)
    }
}

/// The sha256 a sliced job records as its `manifest_sha256`: of its pages' sha256s, one a line.
pub fn index_sha256(pages: &[ManifestPage]) -> String {
    use sha2::{Digest, Sha256};
    let mut h = Sha256::new();
    for p in pages {
        h.update(p.sha256.as_bytes());
        h.update(b"\n");
    }
    crate::hex::hex(&h.finalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn page_lines_read_back_and_others_are_refused() {
        let e = SliceEntry {
            shard: 7,
            first: 1792,
            items: 256,
            sha256: "ab".repeat(32),
        };
        let line = e.line();
        assert_eq!(SliceEntry::parse(line.trim_end()), Some(e));
        for bad in [
            "7\t1792\t256",
            "7\t1792\t256\tzz",
            "x\t1\t2\t",
            "7\t1\t2\tab\textra",
        ] {
            assert_eq!(SliceEntry::parse(bad), None, "{bad}");
        }
    }
}
