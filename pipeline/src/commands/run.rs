//! `sparc3d run JOB [--workers N] [--item-timeout 10m] [--item-memory 8G]`: the local
//! orchestrator. Runs up to N `sparc3d work --events` processes, one shard each, shows
//! progress, and stops cleanly on Ctrl-C or SIGTERM; a later `run` resumes.
//! `sparc3d run DIR_OR_MANIFEST --job OUT` first makes the job OUT (as `manifest build` and
//! `init` would) when it does not exist yet, and resumes it when it does.
//!
//! Its workers die with it (they stop as on SIGTERM when `run` is killed, releasing their
//! leases). A shard leased by another live worker (another `run`, a cluster task, or the
//! workers of a `run` just killed) is waited for and taken over once its lease is released
//! or expires; a worker of its own that makes no progress past its lease (stopped, hung) is
//! killed and its shard started again on a new worker; one shard's failure does not stop the
//! others; and `run` exits 0 only when every shard is done, otherwise it names what is left
//! and exits non-zero.

use super::work::LimitArgs;
use crate::local_workers::LocalWorkers;
use crate::pool::{self, Pool};
use crate::progress::Progress;
use crate::signals::install_signals;
use crate::summary::{shard_states, summarize, summarize_states, JobSummary};
use crate::units::{format_seconds, parse_duration};
use anyhow::Result;
use sparc3d_workers::store::state::{Check, ShardState};
use sparc3d_workers::Job;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `sparc3d run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A job folder; or, with --job, a folder of meshes or a manifest to make the job from.
    #[arg(value_name = "JOB|DIR|MANIFEST")]
    pub input: PathBuf,
    /// The job folder to run: made from INPUT (a folder of meshes, scanned as `manifest build`
    /// does, or a manifest) with the config flags when it is not a job yet, resumed when it is.
    #[arg(long, value_name = "OUT")]
    pub job: Option<PathBuf>,
    #[command(flatten)]
    pub config: super::init::ConfigArgs,
    /// Worker processes (default: number of cores).
    #[arg(long)]
    pub workers: Option<usize>,
    /// Seconds between progress lines when not on a terminal.
    #[arg(long, default_value = "10s", value_parser = parse_duration)]
    pub log_interval: f64,
    #[command(flatten)]
    pub limits: LimitArgs,
    /// When every shard is done, check this sample of the ok items with pymeshlab (`1%` or a
    /// count), as `sparc3d validate JOB --sample SAMPLE` does.
    #[arg(long, value_name = "SAMPLE")]
    pub validate_sample: Option<crate::sample::SampleSize>,
}

/// Runs `sparc3d run`.
pub fn run(args: Args) -> Result<ExitCode> {
    let job_dir = crate::job_setup::job_for_run(&args.input, args.job.as_deref(), &args.config)?;
    let job = Job::open(&job_dir)?;
    let stop = install_signals()?;
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let workers = args.workers.unwrap_or(cores).max(1);
    let threads = (cores / workers).max(1);
    let start = Instant::now();
    let states = shard_states(&job, Check::Quick)?;
    let before = summarize_states(&job, &states);
    let mut progress = Progress::new(
        job.file.items,
        before.ok,
        before.failed,
        workers,
        args.log_interval,
    );
    let (queue, waiting) = pool::plan(&states, &progress);
    progress.println(&format!(
        "{}: {} items, {} shards left, {workers} workers",
        job_dir.display(),
        before.pending,
        queue.len() + waiting.len()
    ));
    let launcher = LocalWorkers {
        job: &job,
        job_dir: job_dir.clone(),
        limit_args: args.limits.to_args(),
        threads,
    };
    let lease_ttl = std::time::Duration::from_secs_f64(args.limits.lease_ttl.max(0.1));
    let errors = Pool::new(launcher, workers, queue, waiting, lease_ttl)
        .run(&mut progress, &|| stop.requested())?;
    let (ok, failed, retried) = progress.finish();
    let elapsed = start.elapsed().as_secs_f64();
    let after = summarize(&job)?;
    let converted = (after.ok + after.failed).saturating_sub(before.ok + before.failed);
    eprintln!(
        "{converted} items in {} ({ok} ok, {failed} failed in total, {retried} crash retries); \
         {} of {} shards done; item time {:.1}s over {:.1}s wall on {workers} workers",
        format_seconds(elapsed),
        after.shards_done,
        after.shards,
        after.item_seconds - before.item_seconds,
        elapsed,
    );
    // The last line points to the failures, whatever the outcome.
    let failures_hint = || {
        if let Some(hint) = crate::hints::failures(&job_dir, after.failed) {
            eprintln!("{hint}");
        }
    };
    if stop.requested() {
        eprintln!("stopped; `sparc3d run {}` resumes", job_dir.display());
        failures_hint();
        return Ok(stop.exit_code());
    }
    if after.shards_done < after.shards || after.pending > 0 {
        print_unfinished(&job, &after, errors.len())?;
        failures_hint();
        return Ok(ExitCode::FAILURE);
    }
    // A worker killed between a shard's completion record and its cleanup left the shard's
    // journal and lease behind; every shard is done now, so they go.
    for shard in 0..after.shards {
        sparc3d_workers::shard::clear_leftovers(&job, shard, args.limits.lease_ttl)?;
    }
    eprintln!("{}", crate::hints::next_steps(&job_dir, after.shards));
    failures_hint();
    if let Some(sample) = args.validate_sample {
        return super::validate::after_run(&job_dir, sample);
    }
    Ok(ExitCode::SUCCESS)
}

/// Names what is left when shards are not finished, and how to resume.
fn print_unfinished(job: &Job, after: &JobSummary, failed_shards: usize) -> Result<()> {
    let left: Vec<String> = shard_states(job, Check::Quick)?
        .iter()
        .enumerate()
        .filter(|(_, s)| !matches!(s, ShardState::Done(_)))
        .map(|(i, _)| i.to_string())
        .take(20)
        .collect();
    eprintln!(
        "error: {} items in {} shards are not finished (shards {}{}); {}fix the cause and \
         run again to resume (finished items are kept)",
        after.pending,
        after.shards - after.shards_done,
        left.join(", "),
        if after.shards - after.shards_done > 20 {
            ", …"
        } else {
            ""
        },
        if failed_shards == 0 {
            String::new()
        } else {
            format!("{failed_shards} shard(s) failed (above); ")
        },
    );
    Ok(())
}
