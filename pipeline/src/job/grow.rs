//! Growing a job (`add`, `run DIR --job JOB`): the items of a folder or manifest that the job
//! does not have yet (by id) are frozen after its last item, in new shards after its last
//! shard ([`sparc3d_manifests::freeze::Freezer::growing`], streamed as `init` streams);
//! finished shards, the config and the fingerprint are never touched. Under the job lock held
//! exclusively, the new slices and the new last index page are written beside the job's
//! (files named by their content, never rewritten), then `job.json` with the new counts and
//! pages, atomically: a crash before it leaves the job as it was. A job made before slices
//! has its `manifest.jsonl` carried into slices first; one whose earlier `add` (by a build
//! before slices) stopped between rewriting `manifest.jsonl` and `job.json` is finished
//! first ([`finish_interrupted`]).

use super::freeze_rows::freeze_rows;
use super::rows::InputRows;
use anyhow::{bail, Context, Result};
use rayon::prelude::*;
use sparc3d_manifests::freeze::{id_key, Freezer, IdKey};
use sparc3d_schema::job::manifest::index_sha256;
use sparc3d_schema::{JobFile, JobLayout};
use sparc3d_workers::frozen::write::SliceWriter;
use sparc3d_workers::frozen::FrozenManifest;
use sparc3d_workers::fsutil::{bytes_sha256, read_json};
use sparc3d_workers::job::lock::JobLock;
use sparc3d_workers::job::{read_frozen_manifest, write_job_file};
use sparc3d_workers::Job;
use std::collections::{BTreeSet, HashSet};
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

/// Adds the rows of `rows` the job at `root` does not have; the caller holds the job lock
/// exclusively ([`lock_for_add`]). A job made before slices has its frozen manifest carried
/// into slices first (its items, shards and fingerprint unchanged).
pub fn add(root: &Path, mut rows: InputRows) -> Result<Grown> {
    finish_interrupted(root)?;
    let mut job = Job::open(root)?;
    if let FrozenManifest::Whole(items) = &job.manifest {
        into_slices(&job, items)?;
        job = Job::open(root)?;
    }
    let FrozenManifest::Sliced(sliced) = &job.manifest else {
        bail!(
            "{}: its frozen manifest could not be carried into slices",
            root.display()
        );
    };
    let (known, columns) = known_ids(&job)?;
    let writer = SliceWriter::append(&job.layout, &job.file, sliced)?;
    let written = freeze_rows(&mut rows, Freezer::growing(known, columns), writer)?;
    let first = job.file.shards;
    let shards_now: u64 = written.pages.iter().map(|p| p.shards).sum();
    let grown = Grown {
        added: written.frozen.items,
        already: written.frozen.already as usize,
        shards: first..shards_now,
    };
    if grown.added == 0 {
        return Ok(grown);
    }
    let file = JobFile {
        items: written.items,
        shards: shards_now,
        manifest_sha256: index_sha256(&written.pages),
        manifest_pages: Some(written.pages),
        ..job.file
    };
    // job.json last: until it is written, the job is the one it was (the new slices and the
    // new last page are files it does not pin).
    write_job_file(&job.layout, &file)?;
    Ok(grown)
}

/// The keys of the ids of every item of `job` ([`sparc3d_manifests::freeze::id_key`]) and its
/// provenance columns, every slice read (in parallel) and checked.
fn known_ids(job: &Job) -> Result<(HashSet<IdKey>, BTreeSet<String>)> {
    let per_shard: Vec<(Vec<IdKey>, Vec<String>)> = (0..job.file.shards)
        .into_par_iter()
        .map(|shard| {
            let items = job.shard_items(shard)?;
            let keys = items.iter().map(|i| id_key(&i.record.id)).collect();
            // Every item of a shard comes from one manifest, with the same columns.
            let columns = items
                .first()
                .map(|i| i.record.extra.keys().cloned().collect())
                .unwrap_or_default();
            Ok((keys, columns))
        })
        .collect::<Result<_>>()?;
    let mut known = HashSet::with_capacity(job.file.items as usize);
    let mut columns = BTreeSet::new();
    for (keys, names) in per_shard {
        known.extend(keys);
        columns.extend(names);
    }
    Ok((known, columns))
}

/// Carries the frozen manifest of a job made before slices (`manifest.jsonl`, read as
/// `items`) into slices and pins them in `job.json`; `manifest.jsonl` is left as it was.
fn into_slices(job: &Job, items: &[sparc3d_schema::FrozenItem]) -> Result<()> {
    let mut writer = SliceWriter::create(&job.layout, job.file.config.shard_size)?;
    if let Err(e) = writer.push_items(items) {
        writer.abandon();
        return Err(e.into());
    }
    let (pages, _) = writer.finish()?;
    eprintln!(
        "{}: frozen manifest carried into {} slices (one a shard, under manifest/)",
        job.layout.root.display(),
        job.file.shards
    );
    let file = JobFile {
        manifest_sha256: index_sha256(&pages),
        manifest_pages: Some(pages),
        ..job.file.clone()
    };
    write_job_file(&job.layout, &file)?;
    Ok(())
}

/// Finishes an add that was stopped between rewriting `manifest.jsonl` and `job.json`: when the
/// manifest holds more items than `job.json` records and its first lines are exactly the ones
/// recorded (their sha256 is `job.json`'s), `job.json` is written for the whole manifest.
/// Anything else is left for [`Job::open`] to refuse as edited.
fn finish_interrupted(root: &Path) -> Result<()> {
    let layout = JobLayout::new(root);
    let file: JobFile = read_json(&layout.job_file())?;
    if file.manifest_pages.is_some() {
        return Ok(()); // a sliced job's add writes job.json last and nothing before it
    }
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
