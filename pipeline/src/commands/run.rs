//! `sparc3d run JOB [--workers N|auto] [--item-timeout 10m] [--item-memory 8G]`: the local
//! orchestrator. Runs `sparc3d work --events` processes, one shard each, N items at once in
//! all (a worker converts several of its shard's items at once when shards are fewer than N:
//! `lane_plan.rs`), shows progress, and stops cleanly on Ctrl-C or SIGTERM; a later `run`
//! resumes.
//! `sparc3d run DIR_OR_MANIFEST --job OUT` first makes the job OUT (as `manifest build` and
//! `init` would) when it does not exist yet, and resumes it when it does.
//!
//! Its workers die with it (they stop as on SIGTERM when `run` is killed, releasing their
//! leases). A shard leased by another live worker (another `run`, a cluster task, or the
//! workers of a `run` just killed) is waited for and taken over once its lease is released
//! or expires; a worker of its own that makes no progress past its lease (stopped, hung) is
//! killed and its shard started again on a new worker; one shard's failure does not stop the
//! others; and `run` exits 0 only when every shard is done and some item converted, otherwise
//! it names what is left (or that every item failed) and exits non-zero.

use crate::flags::limits::LimitArgs;
use crate::rows::summary::{shard_states, summarize, summarize_states, JobSummary};
use crate::run::local_workers::LocalWorkers;
use crate::run::pool::{self, Pool};
use crate::run::progress::Progress;
use crate::run::signals::{install_signals, Stop};
use crate::util::units::{format_seconds, parse_duration};
use anyhow::Result;
use sparc3d_workers::store::state::{Check, ShardState};
use sparc3d_workers::Job;
use std::path::{Path, PathBuf};
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
    pub config: crate::flags::config::ConfigArgs,
    /// With --job and a manifest: `--path-column` and `--where`, as for `init`.
    #[command(flatten)]
    pub source: crate::flags::source::SourceArgs,
    /// Items converted at once (`auto`, the default: one per core, as far as memory holds
    /// items at their memory limit). A shard's items are spread over several workers' lanes
    /// when there are fewer shards than workers; the shards written are the same for any N.
    /// An N past the items left or what the memory holds at the item limit is taken as that
    /// many, and the run's first line says what was taken and why.
    #[arg(long, value_name = "N|auto", value_parser = parse_workers)]
    pub workers: Option<usize>,
    /// Seconds between progress lines when not on a terminal.
    #[arg(long, default_value = "10s", value_parser = parse_duration)]
    pub log_interval: f64,
    #[command(flatten)]
    pub limits: LimitArgs,
    /// When every shard is done, check this sample of the ok items with pymeshlab (`1%` or a
    /// count), as `sparc3d validate JOB --sample SAMPLE` does.
    #[arg(long, value_name = "SAMPLE")]
    pub validate_sample: Option<crate::rows::sample::SampleSize>,
}

/// Runs `sparc3d run`.
pub fn run(args: Args) -> Result<ExitCode> {
    let requested = args.workers.filter(|&n| n > 0);
    if let (sparc3d_bucket::JobHome::Bucket(url), None) =
        (sparc3d_bucket::JobHome::parse(&args.input)?, &args.job)
    {
        return crate::job::bucket_home::run(&url, &args.input, requested, &args.limits.to_args());
    }
    let job_dir = crate::job::setup::job_for_run(
        &args.input,
        args.job.as_deref(),
        &args.config,
        &args.source,
    )?;
    let _lock = crate::job::setup::hold_shared(&job_dir)?;
    let job = Job::open_checked(&job_dir)?;
    let stop = install_signals()?;
    let ran = run_shards(&args, &job, &job_dir, requested, &stop)?;
    conclude(&args, &job, &job_dir, &stop, &ran)
}

/// What a run of the pool left: the job's progress after it, how many shards failed and
/// whether the pool itself failed.
struct Ran {
    after: JobSummary,
    failed_shards: usize,
    pool_failed: bool,
}

/// Runs the job's unfinished shards on `requested` local workers (or as many as the machine
/// holds) until they are finished or `stop` is requested, then says what was converted.
fn run_shards(
    args: &Args,
    job: &Job,
    job_dir: &Path,
    requested: Option<usize>,
    stop: &Stop,
) -> Result<Ran> {
    let start = Instant::now();
    let states = shard_states(job, Check::Quick)?;
    let before = summarize_states(job, &states);
    let machine = crate::util::machine::Machine {
        items: before.pending,
        cores: crate::util::machine::cores(),
        memory: crate::util::machine::available_memory(),
        item_memory: args.limits.apply(job.file.config.limits).item_memory_bytes,
    };
    let plan =
        crate::util::machine::plan(requested, machine, crate::util::machine::threads_from_env());
    let workers = plan.workers;
    let mut progress = Progress::new(
        job.file.items,
        before.ok,
        before.failed,
        workers,
        args.log_interval,
    );
    let (queue, waiting) = pool::plan(&states, &progress);
    progress.println(&format!(
        "{}: {} items, {} shards left, {}",
        job_dir.display(),
        before.pending,
        queue.len() + waiting.len(),
        plan.why
    ));
    let launcher = LocalWorkers {
        job,
        job_dir: job_dir.to_path_buf(),
        limit_args: args.limits.to_args(),
        threads: plan.threads.max(1),
    };
    // An error of the pool itself (a worker that cannot be started: too many open files) ends
    // the run like a failed shard: said, then what is left is named below.
    let lease_ttl = std::time::Duration::from_secs_f64(args.limits.lease_ttl.max(0.1));
    let pool = Pool::new(launcher, workers, queue, waiting, lease_ttl).with_threads(plan.threads);
    let (errors, pool_error) = match pool.run(&mut progress, &|| stop.requested()) {
        Ok(errors) => (errors, None),
        Err(e) => (Vec::new(), Some(e)),
    };
    let counts = progress.finish();
    if let Some(e) = &pool_error {
        eprintln!(
            "error: {}{}",
            crate::util::error_line::describe(e),
            os_hint(e)
        );
    }
    let elapsed = start.elapsed().as_secs_f64();
    let after = summarize(job)?;
    let converted = (after.ok + after.failed).saturating_sub(before.ok + before.failed);
    eprintln!(
        "{converted} items in {} ({} ok, {} failed in total, {} crash retries); {} of {} shards \
         done; item time {:.1}s over {:.1}s wall on {workers} workers (most items at once: {})",
        format_seconds(elapsed),
        counts.ok,
        counts.failed,
        counts.retried,
        after.shards_done,
        after.shards,
        after.item_seconds - before.item_seconds,
        elapsed,
        counts.most_at_once,
    );
    Ok(Ran {
        after,
        failed_shards: errors.len(),
        pool_failed: pool_error.is_some(),
    })
}

/// After the pool: says how the run ended (stopped, shards left, no item converted, or done
/// with the next commands), clears what workers killed after their commit left behind, runs
/// `--validate-sample`, and gives the exit code.
fn conclude(args: &Args, job: &Job, job_dir: &Path, stop: &Stop, ran: &Ran) -> Result<ExitCode> {
    let after = &ran.after;
    // The last line points to the failures, whatever the outcome.
    let failures_hint = || {
        if let Some(hint) = crate::util::hints::failures(job_dir, after.failed) {
            eprintln!("{hint}");
        }
    };
    if stop.requested() {
        eprintln!("stopped; `sparc3d run {}` resumes", job_dir.display());
        failures_hint();
        return Ok(stop.exit_code());
    }
    let unfinished = after.shards_done < after.shards || after.pending > 0;
    if unfinished || ran.pool_failed {
        if unfinished {
            print_unfinished(job, after, ran.failed_shards)?;
        }
        failures_hint();
        return Ok(ExitCode::FAILURE);
    }
    // A worker killed between a shard's completion record and its cleanup left the shard's
    // journal and lease behind; every shard is done now, so they go.
    for shard in 0..after.shards {
        sparc3d_workers::shard::clear_leftovers(job, shard, args.limits.lease_ttl)?;
    }
    if after.ok == 0 && after.failed > 0 {
        print_all_failed(job_dir, after);
        return Ok(ExitCode::FAILURE);
    }
    eprintln!("{}", crate::util::hints::next_steps(job_dir, after.shards));
    failures_hint();
    if let Some(sample) = args.validate_sample {
        return super::validate::after_run(job_dir, sample);
    }
    Ok(ExitCode::SUCCESS)
}

/// `--workers N` or `auto` (given as 0: the run picks).
fn parse_workers(s: &str) -> Result<usize, String> {
    if s.eq_ignore_ascii_case("auto") {
        return Ok(0);
    }
    match s.parse::<usize>() {
        Ok(n) if n > 0 => Ok(n),
        _ => Err(format!(
            "{s:?} is not a number of workers (1 or more) or `auto`"
        )),
    }
}

/// The hint for an I/O error inside `e` (the open-file limit, a full disk), or nothing.
fn os_hint(e: &anyhow::Error) -> String {
    e.chain()
        .find_map(|c| c.downcast_ref::<std::io::Error>())
        .map(sparc3d_workers::error::hint)
        .unwrap_or_default()
}

/// Names what is left when shards are not finished, and how to resume.
fn print_unfinished(job: &Job, after: &JobSummary, failed_shards: usize) -> Result<()> {
    let left: Vec<String> = shard_states(job, Check::Quick)?
        .iter()
        .enumerate()
        .filter(|(_, s)| !matches!(s, ShardState::Done(_)))
        .map(|(i, _)| i.to_string())
        .collect();
    let failed = if failed_shards == 0 {
        String::new()
    } else {
        format!("{failed_shards} shard(s) failed (above); ")
    };
    if left.is_empty() {
        // Every shard is done, yet items have no row: the job's files disagree with each
        // other (never the case for a job as init wrote it, which `Job::open` checks).
        eprintln!(
            "error: every shard is done but {} of {} items have no row in them; {failed}`sparc3d \
             verify {}` checks the shards against their records",
            after.pending,
            after.items,
            job.layout.root.display()
        );
        return Ok(());
    }
    eprintln!(
        "error: {} items in {} shards are not finished (shards {}{}); {failed}fix the cause and \
         run again to resume (finished items are kept)",
        after.pending,
        left.len(),
        left.iter().take(20).cloned().collect::<Vec<_>>().join(", "),
        if left.len() > 20 { ", …" } else { "" },
    );
    Ok(())
}

/// Says that no item of a finished job converted: a cause shared by every item (a wrong path
/// column, an unreadable folder, a config every mesh fails with) is not a success.
fn print_all_failed(job_dir: &Path, after: &JobSummary) {
    let mut classes: Vec<_> = after.error_classes.iter().collect();
    classes.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
    let classes: Vec<String> = classes.iter().map(|(c, n)| format!("{n} {c}")).collect();
    eprintln!(
        "error: no item converted: all {} items failed ({}); a cause that affects every item is \
         likely (a path column of URLs or of another machine's paths, an unreadable folder, a \
         config every mesh fails with): `sparc3d failures {}` says why",
        after.failed,
        classes.join(", "),
        job_dir.display()
    );
}
