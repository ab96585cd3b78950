//! Frozen items as JSON lines: one [`FrozenItem`] a line, as `manifest.jsonl` and every slice
//! hold them, parsed with the order they must have.

use crate::error::{Result, WorkerError};
use sparc3d_schema::FrozenItem;
use std::path::Path;

/// What the lines of one file must be: indices from `first` on, in order; each in `shard` when
/// one is given.
#[derive(Debug, Clone, Copy)]
pub struct Expected {
    /// Index of the first line's item.
    pub first: u64,
    /// The shard of every item, when the file is one shard's slice.
    pub shard: Option<u64>,
}

/// Parses the frozen lines `bytes` of the file at `path`, each checked against `expected`.
pub fn parse(path: &Path, bytes: &[u8], expected: Expected) -> Result<Vec<FrozenItem>> {
    let mut items = Vec::new();
    for (n, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let bad = |reason: String| WorkerError::BadFile {
            path: path.to_path_buf(),
            reason: format!("line {}: {reason}", n + 1),
        };
        let line = std::str::from_utf8(line).map_err(|e| bad(e.to_string()))?;
        if line.trim().is_empty() {
            continue;
        }
        let item: FrozenItem = serde_json::from_str(line).map_err(|e| bad(e.to_string()))?;
        if item.index != expected.first + items.len() as u64 {
            return Err(bad(format!("index {} out of order", item.index)));
        }
        if let Some(shard) = expected.shard.filter(|&s| s != item.shard) {
            return Err(bad(format!(
                "item {} is in shard {}, in the slice of shard {shard}",
                item.index, item.shard
            )));
        }
        items.push(item);
    }
    Ok(items)
}

/// The frozen lines of `items`: each item's JSON and a newline, the bytes `init` writes.
pub fn write(items: &[FrozenItem]) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    for item in items {
        serde_json::to_writer(&mut out, item).map_err(|e| sparc3d_schema::SchemaError::Json {
            context: format!("writing frozen item {}", item.index),
            source: e,
        })?;
        out.push(b'\n');
    }
    Ok(out)
}
