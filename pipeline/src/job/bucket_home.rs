//! The commands' side of jobs whose home is a bucket (`sparc3d_bucket`): the JOB argument
//! of a read-only command made a local view, `init` to a URL, and `run` on one.

use anyhow::{Context, Result};
use sparc3d_bucket::{scratch, view, JobHome};
use sparc3d_sources::objects::Prefix;
use sparc3d_sources::RemoteUrl;
use std::path::{Path, PathBuf};

/// The objects of the bucket job at `url`.
pub fn prefix(url: &RemoteUrl) -> Result<Prefix<'static>> {
    let fetcher = sparc3d_sources::shared().context("setting up the object store client")?;
    Ok(fetcher.prefix(url)?)
}

/// Whether JOB names a bucket prefix.
pub fn is_bucket(job: &Path) -> bool {
    matches!(JobHome::parse(job), Ok(JobHome::Bucket(_)))
}

/// Refuses a command not yet available for a job whose home is a bucket (`what` says which),
/// saying what to do instead.
pub fn refuse(job: &Path, what: &str) -> Result<()> {
    if is_bucket(job) {
        anyhow::bail!(
            "{}: {what} for a job whose home is a bucket yet (docs/CLUSTER.md, \"Jobs in a \
             bucket\"); make a new job for new items, or run the job in a folder",
            job.display()
        );
    }
    Ok(())
}

/// The folder a read-only command reads for JOB: JOB itself when it is a folder; for a bucket
/// URL, a local view with every finished shard (downloaded once, kept while the bucket holds
/// the same objects), said on stderr with the shards whose object is not the recorded one.
pub fn local_view(job: &Path) -> Result<PathBuf> {
    let url = match JobHome::parse(job)? {
        JobHome::Folder(dir) => return Ok(dir),
        JobHome::Bucket(url) => url,
    };
    let (_, local, mirrored) = mirrored(&url)?;
    let dir = local.layout.root;
    eprintln!(
        "{url}: read through a local copy in {} ({} shards downloaded now)",
        dir.display(),
        mirrored.fetched
    );
    for (shard, why) in &mirrored.damaged {
        eprintln!(
            "warning: {url}: shard {shard}: {why}; `sparc3d verify {url}` hashes it and moves \
             it aside if damaged, then `sparc3d run {url}` converts it again"
        );
    }
    Ok(dir)
}

/// The view folder of the bucket job at `url` (`view/` of its scratch folder) with the job
/// files and every finished shard copied; the job's objects, the copy opened as the read-only
/// commands open a job, and what the copy found.
fn mirrored(url: &RemoteUrl) -> Result<(Prefix<'static>, sparc3d_workers::Job, view::Mirrored)> {
    let prefix = prefix(url)?;
    let (local, _) = view_job(url, &prefix)?;
    scratch::pull_all_slices(&prefix, &local)?;
    let mirrored = view::mirror(&prefix, &local)?;
    Ok((prefix, local, mirrored))
}

/// The job files of the bucket job at `url` in its view folder, opened read-only (with the
/// warnings of a job edited after `init`).
pub fn view_job(
    url: &RemoteUrl,
    prefix: &Prefix<'_>,
) -> Result<(sparc3d_workers::Job, Vec<String>)> {
    let dir = scratch::folder(url, None).join("view");
    scratch::pull_job(prefix, &dir, true)
}

/// The local copy of the bucket job at `url` that a worker works in (`work/` of its scratch
/// folder), opened as `run` and `work` open a job.
pub fn work_copy(url: &RemoteUrl, scratch_base: Option<&Path>) -> Result<sparc3d_workers::Job> {
    let prefix = prefix(url)?;
    let dir = scratch::folder(url, scratch_base).join("work");
    Ok(scratch::pull_job(&prefix, &dir, false)?.0)
}

/// `init URL`: the job is made in a fresh local folder as for any job, then published.
pub fn init(
    url: &RemoteUrl,
    rows: super::rows::InputRows,
    config: sparc3d_schema::JobConfig,
) -> Result<()> {
    let prefix = prefix(url)?;
    let staging = scratch::folder(url, None).join("init");
    let _ = std::fs::remove_dir_all(&staging);
    if prefix.get(sparc3d_bucket::keys::JOB_FILE)?.is_some() {
        let (job, _) = scratch::pull_job(&prefix, &staging, true)?;
        scratch::pull_all_slices(&prefix, &job)?;
    }
    let shown = PathBuf::from(url.to_string());
    super::create::create_named(&staging, &shown, rows, config)?;
    sparc3d_bucket::publish::publish(&prefix, &staging)?;
    Ok(())
}

/// The progress of the bucket job at `url`, from its records, leases and checkpoints
/// (nothing of a finished shard but its record is read).
pub fn summarize(url: &RemoteUrl) -> Result<crate::rows::summary::JobSummary> {
    let prefix = prefix(url)?;
    let dir = scratch::folder(url, None).join("status");
    let (job, problems) = scratch::pull_job(&prefix, &dir, true)?;
    for p in &problems {
        eprintln!("warning: {url}: {p}");
    }
    let states = view::shard_states(&prefix, &job)?;
    Ok(crate::rows::summary::summarize_states(&job, &states))
}

/// `run URL`: `workers` processes of `sparc3d work URL --all` on this machine (each takes
/// the shards no live worker holds), then the job's progress; exits 0 when every shard is
/// done.
pub fn run(
    url: &RemoteUrl,
    arg: &Path,
    workers: Option<usize>,
    limit_args: &[String],
) -> Result<std::process::ExitCode> {
    // The job files, read once here: a bad URL or missing job is said once, not per worker.
    work_copy(url, None)?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let workers = workers.unwrap_or(cores).max(1);
    let exe = std::env::current_exe().context("locating the sparc3d binary")?;
    eprintln!("{url}: {workers} workers");
    let mut children = Vec::new();
    for _ in 0..workers {
        let child = std::process::Command::new(&exe)
            .arg("work")
            .arg(arg)
            .arg("--all")
            .args(limit_args)
            .arg("--parent-pid")
            .arg(std::process::id().to_string())
            .spawn()
            .context("starting a worker")?;
        children.push(child);
    }
    let mut failed = 0;
    for mut child in children {
        if !child.wait().is_ok_and(|s| s.success()) {
            failed += 1;
        }
    }
    let s = summarize(url)?;
    eprintln!(
        "{} of {} shards done: {} ok, {} failed, {} pending",
        s.shards_done, s.shards, s.ok, s.failed, s.pending
    );
    if s.shards_done < s.shards || failed > 0 {
        eprintln!(
            "error: {} shards not done{}; `sparc3d run {url}` resumes (finished items are kept \
             in the bucket)",
            s.shards - s.shards_done,
            if failed > 0 {
                format!(", {failed} workers failed (above)")
            } else {
                String::new()
            }
        );
        return Ok(std::process::ExitCode::FAILURE);
    }
    Ok(std::process::ExitCode::SUCCESS)
}

/// The local view `retry` reads for the bucket job at `url`: the finished shards (as for the
/// read-only commands), the leases as lease files and the unfinished shards' checkpoints as
/// journals, so that it sees each shard's state as on disk.
pub fn retry_view(url: &RemoteUrl) -> Result<PathBuf> {
    let (prefix, local, _) = mirrored(url)?;
    let states = view::shard_states(&prefix, &local)?;
    for (shard, state) in states.iter().enumerate() {
        let lease = local.layout.lease(shard as u64);
        let _ = std::fs::remove_file(&lease);
        if let sparc3d_workers::store::state::ShardState::Running(info) = state {
            std::fs::create_dir_all(local.layout.state_dir())?;
            std::fs::write(&lease, serde_json::to_vec(info)?)?;
        }
    }
    Ok(local.layout.root)
}
