//! A job folder read into memory: its job file and frozen manifest.

use crate::error::{Result, WorkerError};
use crate::fsutil::{read_json, write_atomic};
use sparc3d_schema::{FrozenItem, JobFile, JobLayout};
use std::path::Path;

/// Writes `file` as the job file of `layout` (atomically: a reader sees the old file or the
/// new one), as `init` makes it and `add` rewrites it.
pub fn write_job_file(layout: &JobLayout, file: &JobFile) -> Result<()> {
    let bytes = serde_json::to_vec_pretty(file).map_err(|e| WorkerError::BadFile {
        path: layout.job_file(),
        reason: e.to_string(),
    })?;
    write_atomic(&layout.job_file(), &bytes, "writing job file")
}

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
    /// Opens the job folder `root` (written by `sparc3d init`) for a command that changes it
    /// or trusts it (`run`, `work`, `retry`, `verify`, `submit`, `init` again): a job whose
    /// files no longer match what `init` recorded (a hand edit of `job.json` or
    /// `manifest.jsonl`, a config out of range: [`crate::job_files::problems`]) is refused,
    /// naming each file and what differs.
    pub fn open(root: &Path) -> Result<Self> {
        let (job, problems) = Self::open_read_only(root)?;
        if problems.is_empty() {
            return Ok(job);
        }
        Err(WorkerError::EditedJob {
            root: root.to_path_buf(),
            problems,
        })
    }

    /// Opens the job folder `root` for a command that only reads it (`status`, `ls`,
    /// `failures`, `inspect`, ...): also a job whose files were edited after `init`, with what
    /// was found ([`crate::job_files::problems`]; empty when nothing was), for the command to
    /// say.
    pub fn open_read_only(root: &Path) -> Result<(Self, Vec<String>)> {
        let layout = JobLayout::new(root);
        let job_file = layout.job_file();
        if !job_file.exists() {
            return Err(WorkerError::BadFile {
                path: job_file,
                reason: "not a job folder (run `sparc3d init` first)".into(),
            });
        }
        let file: JobFile = read_json(&job_file)?;
        let manifest = layout.manifest();
        let bytes =
            std::fs::read(&manifest).map_err(|e| WorkerError::io("reading", &manifest, e))?;
        let items = parse_frozen_manifest(&manifest, &bytes)?;
        if items.len() as u64 != file.items {
            return Err(WorkerError::BadFile {
                path: layout.manifest(),
                reason: format!("{} items, job.json says {}", items.len(), file.items),
            });
        }
        let problems = crate::job_files::problems(&layout, &file, &items, &bytes);
        let job = Self {
            layout,
            file,
            items,
        };
        Ok((job, problems))
    }

    /// The items of one shard, in manifest order: those frozen with that shard (`index /
    /// shard_size` for a job made at once; a grown job's later items start new shards).
    pub fn shard_items(&self, shard: u64) -> &[FrozenItem] {
        let start = self.items.partition_point(|i| i.shard < shard);
        let end = self.items.partition_point(|i| i.shard <= shard);
        &self.items[start..end.max(start)]
    }

    /// The job's fingerprint.
    pub fn fingerprint(&self) -> &str {
        &self.file.fingerprint
    }
}

/// Reads a frozen manifest (`manifest.jsonl`).
pub fn read_frozen_manifest(path: &Path) -> Result<Vec<FrozenItem>> {
    let bytes = std::fs::read(path).map_err(|e| WorkerError::io("reading", path, e))?;
    parse_frozen_manifest(path, &bytes)
}

/// Parses the bytes of the frozen manifest at `path`: one item per line, in index order.
fn parse_frozen_manifest(path: &Path, bytes: &[u8]) -> Result<Vec<FrozenItem>> {
    let mut items = Vec::new();
    for (n, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = std::str::from_utf8(line).map_err(|e| WorkerError::BadFile {
            path: path.to_path_buf(),
            reason: format!("line {}: {e}", n + 1),
        })?;
        if line.trim().is_empty() {
            continue;
        }
        let item: FrozenItem = serde_json::from_str(line).map_err(|e| WorkerError::BadFile {
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
