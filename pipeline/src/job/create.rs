//! Making a job folder from a folder's or manifest's rows and a config: the frozen manifest in
//! slices (streamed: `init` of ten million rows holds a few batches), every item's shard, then
//! `job.json` with the fingerprint and the index pages' sha256s (its presence is what makes the
//! folder a job, [`is_job`]). Making it again with the same config and manifest does nothing;
//! another config or manifest, or files edited since, are refused.

use super::config::check_same_config_of;
use super::freeze_rows::{freeze_rows, Written};
use super::rows::InputRows;
use anyhow::{bail, Result};
use sparc3d_manifests::freeze::Freezer;
use sparc3d_schema::job::manifest::index_sha256;
use sparc3d_schema::{JobConfig, JobFile, JobLayout};
use sparc3d_workers::frozen::lines;
use sparc3d_workers::frozen::write::SliceWriter;
use sparc3d_workers::frozen::{FrozenManifest, Sliced};
use sparc3d_workers::{Job, WorkerError};
use std::path::Path;

/// Whether `dir` is a job folder (it has its job file).
pub fn is_job(dir: &Path) -> bool {
    JobLayout::new(dir).job_file().exists()
}

/// Creates the job folder `job` from the rows of a folder or manifest and a config: the frozen
/// manifest in slices, the shard of every item, the job file. An existing job with the same
/// config and manifest is left as it is; one with another config or manifest is refused.
pub fn create(job: &Path, rows: InputRows, config: JobConfig) -> Result<()> {
    create_named(job, job, rows, config)
}

/// [`create`] in the folder `job`, naming the job `shown` in messages (`init` to a bucket
/// makes the job in a local folder first).
pub fn create_named(
    job: &Path,
    shown: &Path,
    mut rows: InputRows,
    config: JobConfig,
) -> Result<()> {
    let layout = JobLayout::new(job);
    if layout.job_file().exists() {
        return init_again(&layout, shown, rows, &config);
    }
    let writer = SliceWriter::create(&layout, config.shard_size)?;
    let written = freeze_rows(&mut rows, Freezer::new(), writer)?;
    if written.items == 0 {
        bail!("{}: no meshes to convert", shown.display());
    }
    sparc3d_workers::fsutil::create_dir(&layout.shards_dir())?;
    sparc3d_workers::fsutil::create_dir(&layout.state_dir())?;
    let shards = written.pages.iter().map(|p| p.shards).sum();
    let file = JobFile {
        schema_version: sparc3d_schema::SCHEMA_VERSION,
        tool_version: sparc3d_schema::TOOL_VERSION.into(),
        fingerprint: config.fingerprint()?,
        config,
        items: written.items,
        shards,
        manifest_sha256: index_sha256(&written.pages),
        manifest_pages: Some(written.pages),
    };
    // job.json last: its presence is what makes the folder a job.
    sparc3d_workers::job::write_job_file(&layout, &file)?;
    eprintln!(
        "initialised {}: {} items in {} shards, fingerprint {}{}",
        shown.display(),
        file.items,
        shards,
        &file.fingerprint[..12],
        file.config
            .preset
            .as_ref()
            .map(|p| format!(", made for {p}"))
            .unwrap_or_default()
    );
    Ok(())
}

/// `init` on a job that exists: the rows are frozen aside (in a staging folder inside the
/// job, removed after) and compared with the job's frozen manifest. The same config and
/// manifest do nothing; another config, another manifest, or job files edited since are
/// refused, naming what differs (for an edited frozen manifest, the first line where it
/// differs from what this manifest freezes to).
fn init_again(
    layout: &JobLayout,
    shown: &Path,
    mut rows: InputRows,
    config: &JobConfig,
) -> Result<()> {
    let staging = JobLayout::new(layout.root.join(format!(".init-{}", std::process::id())));
    let result = (|| {
        let writer = SliceWriter::create(&staging, config.shard_size)?;
        let written = freeze_rows(&mut rows, Freezer::new(), writer)?;
        compare_frozen(layout, &staging, written, shown, config)
    })();
    let _ = std::fs::remove_dir_all(&staging.root);
    result
}

/// The end of [`init_again`]: the job at `layout` against the same rows frozen now into
/// `staging`.
fn compare_frozen(
    layout: &JobLayout,
    staging: &JobLayout,
    written: Written,
    shown: &Path,
    config: &JobConfig,
) -> Result<()> {
    let (existing, mut problems) = Job::open_read_only(&layout.root)?;
    if let FrozenManifest::Sliced(s) = &existing.manifest {
        problems.extend(s.problems());
    }
    let staged_file = JobFile {
        items: written.items,
        shards: written.pages.iter().map(|p| p.shards).sum(),
        manifest_sha256: index_sha256(&written.pages),
        manifest_pages: Some(written.pages.clone()),
        config: config.clone(),
        ..existing.file.clone()
    };
    let staged = FrozenManifest::Sliced(Sliced::new(staging, &staged_file, written.pages, false));
    let same_manifest = match &existing.manifest {
        FrozenManifest::Sliced(s) => Some(s.pages()) == staged_file.manifest_pages.as_deref(),
        FrozenManifest::Whole(_) => {
            existing.file.manifest_sha256 == whole_sha256(&staged, staged_file.shards)?
        }
    };
    let theirs = match same_manifest {
        true => "it froze",
        false => "this manifest freezes to",
    };
    let first = first_difference(&existing, &staged, staged_file.shards, theirs)?;
    if !problems.is_empty() {
        let refusal = named_as(
            WorkerError::EditedJob {
                root: layout.root.clone(),
                problems,
            },
            &layout.root,
            shown,
        );
        let Some(at) = first else {
            return Err(refusal.into());
        };
        let line = match same_manifest {
            true => format!(
                "this manifest is the one {} was made from, but its frozen copy was edited \
                 since: {at}",
                shown.display()
            ),
            false => format!(
                "its frozen copy was edited since `init` (and this manifest is not the one {} \
                 was made from); the frozen copy first differs from this manifest at {at}",
                shown.display()
            ),
        };
        return Err(anyhow::Error::new(refusal).context(line));
    }
    check_same_config_of(&existing, config, shown)?;
    if first.is_some() {
        bail!(
            "{} is already initialised with a different manifest ({} items, now {}); shard \
             assignment never changes: use a new job folder",
            shown.display(),
            existing.file.items,
            staged_file.items
        );
    }
    eprintln!(
        "{} is already initialised with this config and manifest; nothing to do",
        shown.display()
    );
    Ok(())
}

/// The sha256 of `manifest`'s frozen lines in one file, as a job made before slices records
/// it.
fn whole_sha256(manifest: &FrozenManifest, shards: u64) -> Result<String> {
    use sha2::{Digest, Sha256};
    let mut h = Sha256::new();
    for shard in 0..shards {
        h.update(lines::write(&manifest.shard_items(shard)?)?);
    }
    Ok(sparc3d_schema::hex::hex(&h.finalize()))
}

/// The first line where the job's frozen manifest differs from `staged` (`shards` shards), as
/// `line N: now, where THEIRS meant`; `None` when they are the same.
fn first_difference(
    job: &Job,
    staged: &FrozenManifest,
    shards: u64,
    theirs: &str,
) -> Result<Option<String>> {
    let (mut now_count, mut meant_count) = (0u64, 0u64);
    let mut now = job.items();
    let mut meant = staged.iter(shards);
    loop {
        let (a, b) = (now.next().transpose()?, meant.next().transpose()?);
        now_count += u64::from(a.is_some());
        meant_count += u64::from(b.is_some());
        match (a, b) {
            (None, None) => return Ok(None),
            (Some(a), Some(b)) if a == b => continue,
            (Some(a), Some(b)) => {
                let (a, b) = (serde_json::to_string(&a)?, serde_json::to_string(&b)?);
                return Ok(Some(format!("line {now_count}: {a}, where {theirs} {b}")));
            }
            _ => break,
        }
    }
    now_count += now.count() as u64;
    meant_count += meant.count() as u64;
    Ok(Some(format!(
        "{now_count} lines, where {theirs} {meant_count}"
    )))
}

/// `e`, a job's refusal, naming the job `shown` rather than the folder `root` it was checked
/// in (a bucket job is checked in a local copy).
fn named_as(
    e: sparc3d_workers::WorkerError,
    root: &Path,
    shown: &Path,
) -> sparc3d_workers::WorkerError {
    use sparc3d_workers::WorkerError;
    match e {
        WorkerError::EditedJob { problems, .. } => WorkerError::EditedJob {
            root: shown.to_path_buf(),
            problems,
        },
        WorkerError::BadFile { path, reason } => WorkerError::BadFile {
            path: path
                .strip_prefix(root)
                .map_or_else(|_| path.clone(), |name| shown.join(name)),
            reason,
        },
        other => other,
    }
}
