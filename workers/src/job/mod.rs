//! A job folder opened: its job file, checked, and its frozen manifest, whose slices are read
//! when asked for ([`crate::frozen`]).

pub mod files;
pub mod lock;

use crate::error::{Result, WorkerError};
use crate::frozen::lines::{self, Expected};
use crate::frozen::{FrozenManifest, Items, Sliced};
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
    /// The frozen manifest: its slices, read on demand (a job made before slices: all of
    /// `manifest.jsonl`).
    pub manifest: FrozenManifest,
}

impl Job {
    /// Opens the job folder `root` (written by `sparc3d init`) for a command that changes it
    /// or trusts it (`run`, `work`, `retry`, `verify`, `submit`, `init` again): a job whose
    /// files no longer match what `init` recorded (a hand edit of `job.json`, a config out of
    /// range: [`crate::job::files::problems`]) is refused, naming each file and what differs; a
    /// slice of the frozen manifest is checked when it is read, and refused the same way.
    pub fn open(root: &Path) -> Result<Self> {
        let (job, problems) = Self::open_with(root, true)?;
        if problems.is_empty() {
            return Ok(job);
        }
        Err(WorkerError::EditedJob {
            root: root.to_path_buf(),
            problems,
        })
    }

    /// [`Job::open`], every slice of the frozen manifest read and checked too: for the
    /// commands that take on the whole job at once (`run`, `retry`, `verify`), so that an
    /// edited slice is refused before anything starts, not when its shard's turn comes.
    pub fn open_checked(root: &Path) -> Result<Self> {
        let job = Self::open(root)?;
        if let FrozenManifest::Sliced(sliced) = &job.manifest {
            let problems = sliced.problems();
            if !problems.is_empty() {
                return Err(WorkerError::EditedJob {
                    root: root.to_path_buf(),
                    problems,
                });
            }
        }
        Ok(job)
    }

    /// Opens the job folder `root` for a command that only reads it (`status`, `ls`,
    /// `failures`, `inspect`, ...): also a job whose files were edited after `init`, with what
    /// was found ([`crate::job::files::problems`]; empty when nothing was), for the command to
    /// say; an edited slice is read with a warning.
    pub fn open_read_only(root: &Path) -> Result<(Self, Vec<String>)> {
        Self::open_with(root, false)
    }

    fn open_with(root: &Path, strict: bool) -> Result<(Self, Vec<String>)> {
        let layout = JobLayout::new(root);
        let job_file = layout.job_file();
        if !job_file.exists() {
            return Err(WorkerError::BadFile {
                path: job_file,
                reason: "not a job folder (run `sparc3d init` first)".into(),
            });
        }
        let file: JobFile = read_json(&job_file)?;
        let mut problems = crate::job::files::job_file_problems(&layout, &file);
        let manifest = match file.manifest_pages.clone() {
            Some(pages) => {
                let sliced = Sliced::new(&layout, &file, pages, strict);
                problems.extend(crate::job::files::pin_problems(&file, &sliced));
                FrozenManifest::Sliced(sliced)
            }
            None => {
                let (items, found) = read_whole(&layout, &file)?;
                problems.extend(found);
                FrozenManifest::Whole(items)
            }
        };
        let job = Self {
            layout,
            file,
            manifest,
        };
        Ok((job, problems))
    }

    /// The items of one shard, in manifest order: those frozen with that shard (`index /
    /// shard_size` for a job made at once; a grown job's later items start new shards).
    pub fn shard_items(&self, shard: u64) -> Result<Vec<FrozenItem>> {
        self.manifest.shard_items(shard)
    }

    /// The item with index `index`, if the job has one (reads its shard's slice).
    pub fn item(&self, index: u64) -> Result<Option<FrozenItem>> {
        self.manifest.item(index)
    }

    /// Every item, in order, streamed a shard at a time.
    pub fn items(&self) -> Items<'_> {
        self.manifest.iter(self.file.shards)
    }

    /// The job's fingerprint.
    pub fn fingerprint(&self) -> &str {
        &self.file.fingerprint
    }
}

/// `manifest.jsonl` of a job made before slices, read whole: its items and what differs from
/// what `init` recorded.
fn read_whole(layout: &JobLayout, file: &JobFile) -> Result<(Vec<FrozenItem>, Vec<String>)> {
    let manifest = layout.manifest();
    let bytes = std::fs::read(&manifest).map_err(|e| WorkerError::io("reading", &manifest, e))?;
    let items = lines::parse(
        &manifest,
        &bytes,
        Expected {
            first: 0,
            shard: None,
        },
    )?;
    if items.len() as u64 != file.items {
        return Err(WorkerError::BadFile {
            path: manifest,
            reason: format!("{} items, job.json says {}", items.len(), file.items),
        });
    }
    let problems = crate::job::files::whole_manifest_problems(file, &items, &bytes);
    Ok((items, problems))
}

/// Reads a frozen manifest in one file (`manifest.jsonl` of a job made before slices).
pub fn read_frozen_manifest(path: &Path) -> Result<Vec<FrozenItem>> {
    let bytes = std::fs::read(path).map_err(|e| WorkerError::io("reading", path, e))?;
    lines::parse(
        path,
        &bytes,
        Expected {
            first: 0,
            shard: None,
        },
    )
}
