//! `sparc3d work JOB (--shard-index I | --array [--shards-per-task K] [--offset O])`: processes
//! shards in this process (one supervised item worker at a time, or `--lanes N` at once). Idempotent: a finished shard
//! is skipped after checking its completion record. For Slurm arrays and Kubernetes indexed
//! jobs, `--array` reads `SLURM_ARRAY_TASK_ID` or `JOB_COMPLETION_INDEX`.

use crate::flags::limits::LimitArgs;
use crate::run::signals::install_signals;
use crate::util::units::parse_duration;
use anyhow::{bail, Context, Result};
use sparc3d_workers::isolate::supervisor::ChildCommand;
use sparc3d_workers::shard::events::Event;
use sparc3d_workers::shard::lanes::{LaneBudget, Share};
use sparc3d_workers::{process_shard, Job, ShardOutcome, WorkOptions};
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d work`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder, or the bucket prefix that is the job's home (s3://, gs://, az://).
    pub job: PathBuf,
    /// Process this shard.
    #[arg(long, conflicts_with_all = ["array", "all"])]
    pub shard_index: Option<u64>,
    /// Take the task index from SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX.
    #[arg(long, conflicts_with = "all")]
    pub array: bool,
    /// Process every shard not done and not leased by a live worker, in order.
    #[arg(long)]
    pub all: bool,
    /// For a job in a bucket: the local scratch folder (default: SPARC3D_SCRATCH, else the
    /// system's temporary folder); it holds a copy of the job files and the shard in progress.
    #[arg(long, value_name = "DIR")]
    pub scratch: Option<PathBuf>,
    /// For a job in a bucket: the most time between checkpoints of a shard in progress (what
    /// a killed worker can lose, besides the item in flight).
    #[arg(long, default_value = "30s", value_parser = parse_duration)]
    pub checkpoint_every: f64,
    /// Shards per array task: task T processes shards O + T·K … O + T·K + K − 1.
    #[arg(long, default_value_t = 1)]
    pub shards_per_task: u64,
    /// First shard of task 0.
    #[arg(long, default_value_t = 0)]
    pub offset: u64,
    /// Print progress events as JSON lines on stdout (used by `run`).
    #[arg(long)]
    pub events: bool,
    /// Items of a shard converted at once, each in its own item worker, with
    /// `RAYON_NUM_THREADS` / N threads each (at least 1) unless `--threads` says otherwise.
    /// The shard written is the same for any N.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=1024))]
    pub lanes: u64,
    /// Threads per conversion (default: the environment's `RAYON_NUM_THREADS`, else the
    /// cores divided among the lanes); more than the machine's cores are taken as its cores,
    /// said on stderr. (`--lanes` past the shard's items starts only as many lanes as items.)
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=4096))]
    pub threads: Option<u64>,
    /// Read new shares (`{"lanes":N,"threads":T}` lines) on stdin while working (used by
    /// `run`, which moves the lanes of finished workers to those with items left).
    #[arg(long, hide = true)]
    pub control_stdin: bool,
    /// Pid of the orchestrator that started this worker: the worker stops (as on SIGTERM)
    /// when it dies, so that no worker outlives `run` holding a lease (used by `run`).
    #[arg(long, hide = true)]
    pub parent_pid: Option<u32>,
    #[command(flatten)]
    pub limits: LimitArgs,
}

/// The task index of an array job from the environment.
pub fn array_task_index() -> Result<u64> {
    for var in ["SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"] {
        if let Ok(v) = std::env::var(var) {
            return v
                .trim()
                .parse()
                .with_context(|| format!("{var}={v:?} is not a task index"));
        }
    }
    bail!("--array needs SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX in the environment")
}

/// How to start item workers: this binary's hidden `item-worker` command.
pub fn child_command(env: Vec<(String, String)>) -> Result<ChildCommand> {
    Ok(ChildCommand {
        program: std::env::current_exe().context("locating the sparc3d binary")?,
        args: vec!["item-worker".into()],
        env,
    })
}

/// Runs `sparc3d work`.
pub fn run(args: Args) -> Result<ExitCode> {
    match sparc3d_bucket::JobHome::parse(&args.job)? {
        sparc3d_bucket::JobHome::Folder(dir) => {
            let _lock = crate::job::setup::hold_shared(&dir)?;
            let job = Job::open(&dir)?;
            work_shards(&args, &job, &mut |job, shard, opts| {
                process_shard(job, shard, opts)
                    .with_context(|| format!("shard {shard} of {}", dir.display()))
            })
        }
        sparc3d_bucket::JobHome::Bucket(url) => {
            let job = crate::job::bucket_home::work_copy(&url, args.scratch.as_deref())?;
            let prefix = crate::job::bucket_home::prefix(&url)?;
            let every = std::time::Duration::from_secs_f64(args.checkpoint_every.max(0.0));
            work_shards(&args, &job, &mut |job, shard, opts| {
                sparc3d_bucket::work::work_shard(&prefix, job, shard, opts, every)
                    .with_context(|| format!("shard {shard} of {url}"))
            })
        }
    }
}

/// The shards `args` name: one, an array task's, or all of the job's.
fn chosen_shards(args: &Args, job: &Job) -> Result<Vec<u64>> {
    Ok(match (args.shard_index, args.array, args.all) {
        (Some(i), _, _) => vec![i],
        (None, true, _) => {
            let t = array_task_index()?;
            let k = args.shards_per_task.max(1);
            (args.offset + t * k..args.offset + t * k + k).collect()
        }
        (None, false, true) => (0..job.file.shards).collect(),
        (None, false, false) => bail!("give --shard-index I, --array or --all"),
    })
}

/// What processes one shard: on disk, or in a bucket.
type ShardFn<'a> = dyn FnMut(&Job, u64, &mut WorkOptions) -> Result<ShardOutcome> + 'a;

/// Processes the shards `args` name with `process`, saying what became of each.
fn work_shards(args: &Args, job: &Job, process: &mut ShardFn<'_>) -> Result<ExitCode> {
    let shards = chosen_shards(args, job)?;
    let stop = install_signals()?;
    if let Some(parent) = args.parent_pid {
        // SIGTERM, not SIGKILL: the worker stops like on Ctrl-C and releases its lease.
        sparc3d_workers::isolate::parent::die_with_parent(parent, libc::SIGTERM);
    }
    let events = args.events;
    let mut opts = WorkOptions {
        child: child_command(Vec::new())?,
        limits: args.limits.apply(job.file.config.limits),
        lease_ttl_s: args.limits.lease_ttl,
        stop: stop.flag.clone(),
        events: Box::new(move |e: Event| report_event(events, &e)),
        after_item: None,
        budget: budget(args),
    };
    for shard in shards {
        if shard >= job.file.shards {
            if !events {
                eprintln!(
                    "shard {shard}: beyond the job's {} shards, nothing to do",
                    job.file.shards
                );
            }
            continue;
        }
        let outcome = process(job, shard, &mut opts)?;
        if !events {
            say_outcome(shard, &outcome);
        }
        // Said also under `run`, whose events carry it too: a stale worker's log must tell.
        if let ShardOutcome::LeaseLost(message) = &outcome {
            eprintln!("{message}");
        }
        if outcome == ShardOutcome::Stopped {
            return Ok(stop.exit_code());
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// This worker's share of the machine: `--lanes` at `--threads` each (by default the cores, or
/// `RAYON_NUM_THREADS`, divided among the lanes), changed by control lines on stdin with
/// `--control-stdin`.
fn budget(args: &Args) -> std::sync::Arc<LaneBudget> {
    let lanes = args.lanes as usize;
    let threads = match args.threads {
        Some(t) => threads_taken(t as usize, crate::util::machine::cores()),
        // One lane keeps today's behaviour: the item worker inherits the environment.
        None if lanes == 1 => 0,
        None => (crate::util::machine::threads_from_env_or_cores() / lanes).max(1),
    };
    let budget = LaneBudget::new(Share { lanes, threads });
    if args.control_stdin {
        sparc3d_workers::shard::lanes::follow_control(
            std::io::BufReader::new(std::io::stdin()),
            budget.clone(),
        );
    }
    budget
}

/// `--threads asked` taken at most as the machine's `cores` (more threads per conversion
/// only contend for them: 4,096 of them on 2 cores stalled the worker), said on stderr when
/// it is fewer than asked.
fn threads_taken(asked: usize, cores: usize) -> usize {
    let taken = asked.min(cores.max(1));
    if taken < asked {
        eprintln!("--threads {asked} taken as {taken} (the cores of this machine)");
    }
    taken
}

/// An event as a JSON line on stdout (`--events`), or the damaged-shard note on stderr.
fn report_event(events: bool, e: &Event) {
    if events {
        if let Ok(line) = serde_json::to_string(e) {
            let mut out = std::io::stdout().lock();
            let _ = writeln!(out, "{line}");
            let _ = out.flush();
        }
    } else if let Event::ShardDamaged {
        shard,
        reason,
        moved_to,
    } = e
    {
        eprintln!(
            "shard {shard}: damaged ({reason}); moved aside to {moved_to}, converting it again"
        );
    }
}

/// What became of a shard, on stderr.
fn say_outcome(shard: u64, outcome: &ShardOutcome) {
    match outcome {
        ShardOutcome::Done(r) => eprintln!(
            "shard {shard}: written, {} rows ({} ok, {} failed)",
            r.rows, r.ok, r.failed
        ),
        ShardOutcome::AlreadyDone(r) => {
            eprintln!("shard {shard}: already done ({} rows)", r.rows)
        }
        ShardOutcome::Busy(owner) => eprintln!("shard {shard}: leased by {owner}, skipped"),
        ShardOutcome::Stopped => eprintln!("shard {shard}: stopped; run again to resume"),
        ShardOutcome::LeaseLost(_) => {}
    }
}
