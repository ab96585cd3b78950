//! A job folder read into memory: its job file and frozen manifest.

use crate::error::{Result, WorkerError};
use crate::fsutil::read_json;
use sparc3d_schema::{FrozenItem, JobFile, JobLayout};
use std::io::BufRead;
use std::path::Path;

/// An initialised job.
#[derive(Debug, Clone)]
pub struct Job {
    /// Where its files are.
    pub layout: JobLayout,
    /// Its config and fingerprint.
    pub file: JobFile,
    /// The frozen manifest, in order.
    pub items: Vec<FrozenItem>,
}

impl Job {
    /// Opens the job folder `root` (written by `sparc3d init`).
    pub fn open(root: &Path) -> Result<Self> {
        let layout = JobLayout::new(root);
        let job_file = layout.job_file();
        if !job_file.exists() {
            return Err(WorkerError::BadFile {
                path: job_file,
                reason: "not a job folder (run `sparc3d init` first)".into(),
            });
        }
        let file: JobFile = read_json(&job_file)?;
        let items = read_frozen_manifest(&layout.manifest())?;
        if items.len() as u64 != file.items {
            return Err(WorkerError::BadFile {
                path: layout.manifest(),
                reason: format!("{} items, job.json says {}", items.len(), file.items),
            });
        }
        Ok(Self {
            layout,
            file,
            items,
        })
    }

    /// The items of one shard, in manifest order.
    pub fn shard_items(&self, shard: u64) -> &[FrozenItem] {
        let size = self.file.config.shard_size.max(1) as usize;
        let start = (shard as usize).saturating_mul(size).min(self.items.len());
        let end = start.saturating_add(size).min(self.items.len());
        &self.items[start..end]
    }

    /// The job's fingerprint.
    pub fn fingerprint(&self) -> &str {
        &self.file.fingerprint
    }
}

/// Reads a frozen manifest (`manifest.jsonl`).
pub fn read_frozen_manifest(path: &Path) -> Result<Vec<FrozenItem>> {
    let f = std::fs::File::open(path).map_err(|e| WorkerError::io("reading", path, e))?;
    let mut items = Vec::new();
    for (n, line) in std::io::BufReader::new(f).lines().enumerate() {
        let line = line.map_err(|e| WorkerError::io("reading", path, e))?;
        if line.trim().is_empty() {
            continue;
        }
        let item: FrozenItem = serde_json::from_str(&line).map_err(|e| WorkerError::BadFile {
            path: path.to_path_buf(),
            reason: format!("line {}: {e}", n + 1),
        })?;
        if item.index != items.len() as u64 {
            return Err(WorkerError::BadFile {
                path: path.to_path_buf(),
                reason: format!("line {}: index {} out of order", n + 1, item.index),
            });
        }
        items.push(item);
    }
    Ok(items)
}
