//! Growing a job (`add`, `run DIR --job JOB`): the items of a folder or manifest that the job
//! does not have yet (by id) are frozen after its last item, in new shards after its last
//! shard ([`sparc3d_manifests::freeze::append`]); finished shards, the config and the
//! fingerprint are never touched. Under the job lock held exclusively, `manifest.jsonl` is
//! rewritten with the new lines appended, then `job.json` with the new counts and the frozen
//! manifest's sha256 (both atomically). A crash between the two leaves a manifest whose first
//! lines are the recorded ones: the next `add` (or `run DIR --job JOB`) finishes it
//! ([`finish_interrupted`]).

use anyhow::{bail, Context, Result};
use sparc3d_manifests::freeze::append;
use sparc3d_manifests::RawRecord;
use sparc3d_schema::{JobFile, JobLayout};
use sparc3d_workers::fsutil::{bytes_sha256, read_json, write_atomic};
use sparc3d_workers::job::{read_frozen_manifest, write_job_file};
use sparc3d_workers::job_lock::JobLock;
use sparc3d_workers::Job;
use std::ops::Range;
use std::path::Path;

/// What an add did.
#[derive(Debug)]
pub struct Grown {
    /// Items added.
    pub added: u64,
    /// Rows left out because the job has their id already.
    pub already: usize,
    /// The new shards.
    pub shards: Range<u64>,
}

/// The job lock of `root` held exclusively, or an error saying who may hold it. `None` when
/// the file system refuses locks (some network file systems): said on stderr, and the add
/// goes on unlocked, as the lock is advisory.
pub fn lock_for_add(root: &Path) -> Result<Option<JobLock>> {
    if !super::create::is_job(root) {
        bail!(
            "{} is not a job folder (it has no job.json); make one with `sparc3d init` or \
             `sparc3d run DIR --job {}`",
            root.display(),
            root.display()
        );
    }
    match JobLock::try_exclusive(&JobLayout::new(root)) {
        Ok(Some(lock)) => Ok(Some(lock)),
        Err(e) => {
            eprintln!(
                "warning: {e}: adding without the job lock; make sure no run or work is on \
                 this job"
            );
            Ok(None)
        }
        Ok(None) => bail!(
            "{} is in use: a `run` or `work` on it, or another `add`, holds its lock \
             (job.lock); nothing was added: add when it has ended",
            root.display()
        ),
    }
}

/// Adds the rows of `records` the job at `root` does not have; the caller holds the job lock
/// exclusively ([`lock_for_add`]).
pub fn add(root: &Path, records: Vec<RawRecord>) -> Result<Grown> {
    finish_interrupted(root)?;
    let job = Job::open(root)?;
    let appended = append(&job.items, records, job.file.config.shard_size)?;
    let first = job.file.shards;
    let shards = first..appended.items.last().map_or(first, |i| i.shard + 1);
    let grown = Grown {
        added: appended.items.len() as u64,
        already: appended.already,
        shards,
    };
    if appended.items.is_empty() {
        return Ok(grown);
    }
    let layout = &job.layout;
    let mut text = std::fs::read(layout.manifest())
        .with_context(|| format!("reading {}", layout.manifest().display()))?;
    for item in &appended.items {
        text.extend_from_slice(serde_json::to_string(item)?.as_bytes());
        text.push(b'\n');
    }
    write_atomic(&layout.manifest(), &text, "growing the frozen manifest")?;
    let file = JobFile {
        items: job.file.items + grown.added,
        shards: grown.shards.end,
        manifest_sha256: bytes_sha256(&text),
        ..job.file
    };
    write_job_file(layout, &file)?;
    Ok(grown)
}

/// Finishes an add that was stopped between rewriting `manifest.jsonl` and `job.json`: when the
/// manifest holds more items than `job.json` records and its first lines are exactly the ones
/// recorded (their sha256 is `job.json`'s), `job.json` is written for the whole manifest.
/// Anything else is left for [`Job::open`] to refuse as edited.
fn finish_interrupted(root: &Path) -> Result<()> {
    let layout = JobLayout::new(root);
    let file: JobFile = read_json(&layout.job_file())?;
    let text = std::fs::read(layout.manifest())
        .with_context(|| format!("reading {}", layout.manifest().display()))?;
    let lines = text.split_inclusive(|&b| b == b'\n');
    let recorded: usize = lines.take(file.items as usize).map(<[u8]>::len).sum();
    let whole = bytes_sha256(&text);
    if whole == file.manifest_sha256 || bytes_sha256(&text[..recorded]) != file.manifest_sha256 {
        return Ok(());
    }
    let items = read_frozen_manifest(&layout.manifest())?;
    eprintln!(
        "{}: finishing an add that was interrupted ({} items recorded, {} frozen)",
        root.display(),
        file.items,
        items.len()
    );
    let file = JobFile {
        items: items.len() as u64,
        shards: items.last().map_or(0, |i| i.shard + 1),
        manifest_sha256: whole,
        ..file
    };
    write_job_file(&layout, &file)?;
    Ok(())
}

/// Says what an add did, for `add` and `run DIR --job JOB`.
pub fn describe(root: &Path, grown: &Grown) -> String {
    if grown.added == 0 {
        return format!(
            "{}: nothing new ({} rows are in the job already)",
            root.display(),
            grown.already
        );
    }
    format!(
        "{}: added {} new items as shards {}..{} ({} rows are in the job already); the \
         finished shards, the config and the fingerprint are unchanged",
        root.display(),
        grown.added,
        grown.shards.start,
        grown.shards.end - 1,
        grown.already
    )
}
