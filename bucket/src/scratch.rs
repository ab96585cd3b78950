//! The local copies a command makes of a job whose home is a bucket, under one scratch folder
//! per job URL: `work/` (the job files, and the shards in progress of this worker) and `view/`
//! (what the read-only commands read). The folder is `--scratch`, else `SPARC3D_SCRATCH`, else
//! the system's temporary folder, each holding `sparc3d-<hash of the URL>/`.

use crate::keys;
use anyhow::{bail, Context, Result};
use sha2::{Digest, Sha256};
use sparc3d_schema::job::manifest::PAGE_SHARDS;
use sparc3d_schema::{JobFile, JobLayout};
use sparc3d_sources::objects::Prefix;
use sparc3d_sources::RemoteUrl;
use sparc3d_workers::frozen::FrozenManifest;
use sparc3d_workers::{Job, WorkerError};
use std::path::{Path, PathBuf};

/// The scratch folder of the job at `url`: `base` (else `SPARC3D_SCRATCH`, else the temporary
/// folder) / `sparc3d-<first 16 hex digits of the URL's sha256>`.
pub fn folder(url: &RemoteUrl, base: Option<&Path>) -> PathBuf {
    let base = base
        .map(Path::to_path_buf)
        .or_else(|| std::env::var_os("SPARC3D_SCRATCH").map(PathBuf::from))
        .unwrap_or_else(std::env::temp_dir);
    let name = url.to_string();
    let digest = Sha256::digest(name.trim_end_matches('/').as_bytes());
    base.join(format!(
        "sparc3d-{}",
        sparc3d_schema::job::config::hex(&digest[..8])
    ))
}

/// Brings `job.json` of the bucket job at `prefix` into `dir` (replacing an older copy) and
/// opens the job there; a job made before slices brings its `manifest.jsonl` too. A sliced
/// job's slices are brought as they are needed ([`pull_slices`]). `read_only` opens it as the
/// read-only commands do.
pub fn pull_job(prefix: &Prefix<'_>, dir: &Path, read_only: bool) -> Result<(Job, Vec<String>)> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let Some(job_file) = prefix
        .get(keys::JOB_FILE)
        .with_context(|| format!("reading {}", prefix.url(keys::JOB_FILE)))?
    else {
        bail!(
            "{}: no job there (no job.json; `sparc3d init {} --manifest ...` makes one)",
            prefix.root(),
            prefix.root()
        );
    };
    let sliced = serde_json::from_slice::<JobFile>(&job_file.bytes)
        .is_ok_and(|f| f.manifest_pages.is_some());
    if !sliced {
        let Some(manifest) = prefix
            .get(keys::MANIFEST)
            .with_context(|| format!("reading {}", prefix.url(keys::MANIFEST)))?
        else {
            bail!("{}: job.json without manifest.jsonl", prefix.root());
        };
        replace(&dir.join(keys::MANIFEST), &manifest.bytes)?;
    }
    replace(&dir.join(keys::JOB_FILE), &job_file.bytes)?;
    let opened = if read_only {
        Job::open_read_only(dir)
    } else {
        Job::open(dir).map(|job| (job, Vec::new()))
    };
    opened.map_err(|e| damaged(prefix, dir, e))
}

/// Brings into the local copy `job` the frozen manifest's files that `shards` need: their
/// index pages and slices, each downloaded once (a file already there with the pinned bytes is
/// kept: the names carry the content's sha256). Nothing for a job made before slices, whose
/// `manifest.jsonl` came with [`pull_job`].
pub fn pull_slices(prefix: &Prefix<'_>, job: &Job, shards: &[u64]) -> Result<()> {
    let FrozenManifest::Sliced(sliced) = &job.manifest else {
        return Ok(());
    };
    let shards: Vec<u64> = shards
        .iter()
        .copied()
        .filter(|&s| s < job.file.shards)
        .collect();
    let mut pages: Vec<u64> = shards.iter().map(|s| s / PAGE_SHARDS).collect();
    pages.sort_unstable();
    pages.dedup();
    let pinned_pages: Vec<(String, String)> = pages
        .iter()
        .map(|&page| {
            let pin = &sliced.pages()[page as usize];
            (JobLayout::page_name(page, &pin.sha256), pin.sha256.clone())
        })
        .collect();
    pull_each_pinned(prefix, job, &pinned_pages)?;
    let mut slices = Vec::with_capacity(shards.len());
    for shard in shards {
        let entry = sliced
            .entry(shard)
            .map_err(|e| damaged(prefix, &job.layout.root, e))?;
        slices.push((JobLayout::slice_name(shard, &entry.sha256), entry.sha256));
    }
    pull_each_pinned(prefix, job, &slices)
}

/// [`pull_pinned`] for each `(name, sha256)`, [`crate::parallel::IN_FLIGHT`] at a time.
fn pull_each_pinned(prefix: &Prefix<'_>, job: &Job, files: &[(String, String)]) -> Result<()> {
    crate::parallel::each(files, crate::parallel::IN_FLIGHT, |(name, sha256)| {
        pull_pinned(prefix, job, name, sha256)
    })?;
    Ok(())
}

/// [`pull_slices`] for every shard of `job`: what a command that reads every item needs.
pub fn pull_all_slices(prefix: &Prefix<'_>, job: &Job) -> Result<()> {
    let shards: Vec<u64> = (0..job.file.shards).collect();
    pull_slices(prefix, job, &shards)
}

/// Downloads `manifest/NAME` into the local copy unless a file with the pinned `sha256` is
/// there; an object missing or with other bytes is a damaged job, said with what to do.
fn pull_pinned(prefix: &Prefix<'_>, job: &Job, name: &str, sha256: &str) -> Result<()> {
    let path = job.layout.manifest_dir().join(name);
    let kept =
        std::fs::read(&path).is_ok_and(|b| sparc3d_workers::fsutil::bytes_sha256(&b) == sha256);
    if kept {
        return Ok(());
    }
    let key = keys::manifest_file(name);
    let Some(object) = prefix
        .get(&key)
        .with_context(|| format!("reading {}", prefix.url(&key)))?
    else {
        bail!(
            "the job at {} is damaged: {} is missing (its job.json pins it); restore it as \
             `init` wrote it, or make the job again under another prefix",
            prefix.root().to_string().trim_end_matches('/'),
            prefix.url(&key)
        );
    };
    let found = sparc3d_workers::fsutil::bytes_sha256(&object.bytes);
    if found != sha256 {
        bail!(
            "the job at {} is damaged: {} has sha256 {found}, not the {sha256} its job pins \
             (replaced after `init`); restore it as `init` wrote it, or make the job again \
             under another prefix",
            prefix.root().to_string().trim_end_matches('/'),
            prefix.url(&key)
        );
    }
    let dir = job.layout.manifest_dir();
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    replace(&path, &object.bytes)
}

/// The error of a bucket job whose files the local copy in `dir` refused: said of the
/// bucket's objects (the copy is only where they were checked), with what to do.
fn damaged(prefix: &Prefix<'_>, dir: &Path, e: WorkerError) -> anyhow::Error {
    let what = match e {
        WorkerError::BadFile { path, reason } if path.starts_with(dir) => {
            let name = path
                .strip_prefix(dir)
                .unwrap_or(&path)
                .display()
                .to_string();
            format!("{}: {reason}", prefix.url(&name))
        }
        WorkerError::EditedJob { problems, .. } => format!(
            "its files are not as `sparc3d init` wrote them: {}",
            problems.join("; ")
        ),
        other => return other.into(),
    };
    anyhow::anyhow!(
        "the job at {} is damaged: {what} (checked in a local copy in {}). If {} or {} were \
         edited, restore them as `init` wrote them; if they come from two `init`s at once with \
         different manifests (possible before sparc3d refused that), the job cannot be \
         repaired: make it again under another prefix, or delete every object under that \
         prefix and run `init` again",
        prefix.root().to_string().trim_end_matches('/'),
        dir.display(),
        prefix.url(keys::JOB_FILE),
        prefix.url(keys::MANIFEST_FILES),
    )
}

/// Writes `bytes` at `path` unless it holds them already (atomically: a temporary file, then
/// a rename).
pub fn replace(path: &Path, bytes: &[u8]) -> Result<()> {
    if std::fs::read(path).is_ok_and(|b| b == bytes) {
        return Ok(());
    }
    sparc3d_workers::fsutil::write_atomic(path, bytes, "writing a local copy")?;
    Ok(())
}
