//! Making a job folder from manifest rows and a config: the frozen manifest, every item's
//! shard, then `job.json` with the fingerprint (its presence is what makes the folder a job,
//! [`is_job`]). Making it again with the same config and manifest does nothing; another config
//! or manifest, or files edited since, are refused.

use super::config::check_same_config_of;
use anyhow::{bail, Result};
use sparc3d_manifests::RawRecord;
use sparc3d_schema::{JobConfig, JobFile, JobLayout};
use std::path::Path;

/// Whether `dir` is a job folder (it has its job file).
pub fn is_job(dir: &Path) -> bool {
    JobLayout::new(dir).job_file().exists()
}

/// Creates the job folder `job` from manifest records and a config: frozen manifest, shard of
/// every item, job file. An existing job with the same config and manifest is left as it is;
/// one with another config or manifest is refused.
pub fn create(job: &Path, records: Vec<RawRecord>, config: JobConfig) -> Result<()> {
    create_named(job, job, records, config)
}

/// [`create`] in the folder `job`, naming the job `shown` in messages (`init` to a bucket
/// makes the job in a local folder first).
pub fn create_named(
    job: &Path,
    shown: &Path,
    records: Vec<RawRecord>,
    config: JobConfig,
) -> Result<()> {
    let layout = JobLayout::new(job);
    let items = sparc3d_manifests::freeze::freeze(records, config.shard_size)?;
    let mut text = String::new();
    for it in &items {
        text.push_str(&serde_json::to_string(it)?);
        text.push('\n');
    }
    let manifest_sha256 = {
        use sha2::{Digest, Sha256};
        sparc3d_schema::config::hex(&Sha256::digest(text.as_bytes()))
    };
    if layout.job_file().exists() {
        let existing = sparc3d_workers::Job::open(&layout.root).map_err(|e| {
            let e = named_as(e, &layout.root, shown);
            match frozen_copy_differs(&layout, shown, &text, &manifest_sha256) {
                Some(line) => anyhow::Error::new(e).context(line),
                None => e.into(),
            }
        })?;
        check_same_config_of(&existing, &config, shown)?;
        if existing.file.manifest_sha256 != manifest_sha256 {
            bail!(
                "{} is already initialised with a different manifest ({} items, now {}); \
                 shard assignment never changes: use a new job folder",
                shown.display(),
                existing.file.items,
                items.len()
            );
        }
        eprintln!(
            "{} is already initialised with this config and manifest; nothing to do",
            shown.display()
        );
        return Ok(());
    }
    sparc3d_workers::fsutil::create_dir(&layout.shards_dir())?;
    sparc3d_workers::fsutil::create_dir(&layout.state_dir())?;
    sparc3d_workers::fsutil::write_atomic(
        &layout.manifest(),
        text.as_bytes(),
        "freezing manifest",
    )?;
    let shards = (items.len() as u64).div_ceil(config.shard_size.max(1) as u64);
    let file = JobFile {
        schema_version: sparc3d_schema::SCHEMA_VERSION,
        tool_version: sparc3d_schema::TOOL_VERSION.into(),
        fingerprint: config.fingerprint()?,
        config,
        items: items.len() as u64,
        shards,
        manifest_sha256,
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

/// When the job's frozen copy is not what `init` froze (its sha256 is not the one `job.json`
/// recorded): the first line where it differs from `text`, the manifest given to `init` again
/// frozen now, for the error that refuses the job. With the manifest the job was made from,
/// that is the edited line; with another, the first line where the two differ.
fn frozen_copy_differs(
    layout: &JobLayout,
    shown: &Path,
    text: &str,
    sha256: &str,
) -> Option<String> {
    let file: JobFile = sparc3d_workers::fsutil::read_json(&layout.job_file()).ok()?;
    let frozen = std::fs::read_to_string(layout.manifest()).ok()?;
    if sparc3d_workers::fsutil::bytes_sha256(frozen.as_bytes()) == file.manifest_sha256 {
        return None; // the frozen copy is as `init` wrote it: something else was edited
    }
    let first = frozen
        .lines()
        .zip(text.lines())
        .enumerate()
        .find(|(_, (a, b))| a != b);
    let differs = |theirs: &str| match first {
        Some((n, (now, meant))) => format!("line {}: {now}, where {theirs} {meant}", n + 1),
        None => format!(
            "{} lines, where {theirs} {}",
            frozen.lines().count(),
            text.lines().count()
        ),
    };
    let copy = shown.join("manifest.jsonl");
    Some(if file.manifest_sha256 == sha256 {
        format!(
            "this manifest is the one {} was made from, but its frozen copy {} was edited \
             since: {}",
            shown.display(),
            copy.display(),
            differs("it froze")
        )
    } else {
        format!(
            "its frozen copy {} was edited since `init` (and this manifest is not the one {} \
             was made from); the frozen copy first differs from this manifest at {}",
            copy.display(),
            shown.display(),
            differs("this manifest freezes to")
        )
    })
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
