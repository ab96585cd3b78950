//! `sparc3d submit slurm JOB [--max-concurrent N] [--shards-per-task K] [--partition P]
//! [--dry-run]`: writes `JOB/slurm/convert.sbatch` and submits array jobs covering only the
//! shards that are not complete (by their completion records) and not already queued by an
//! earlier submission, split under the cluster's `MaxArraySize`. Prints the job ids.

use crate::cluster::slurm::{self, ScriptOptions};
use crate::cluster::slurm_submit::{self as submit, SubmitPlan};
use crate::flags::limits::LimitArgs;
use anyhow::{bail, Context, Result};
use sparc3d_workers::Job;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `sparc3d submit`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    target: Target,
}

#[derive(Debug, clap::Subcommand)]
enum Target {
    /// Submit the unfinished shards of a job as Slurm array jobs.
    Slurm(SlurmArgs),
}

/// Arguments of `sparc3d submit slurm`.
#[derive(Debug, clap::Args)]
pub struct SlurmArgs {
    /// Job folder (on a filesystem every compute node mounts at the same path).
    pub job: PathBuf,
    /// At most this many tasks of each array run at once (`--array=…%N`).
    #[arg(long)]
    pub max_concurrent: Option<u32>,
    /// Shards per array task.
    #[arg(long, default_value_t = 1)]
    pub shards_per_task: u64,
    /// Slurm partition.
    #[arg(long)]
    pub partition: Option<String>,
    /// Time limit per task, in Slurm's syntax (e.g. 4:00:00).
    #[arg(long)]
    pub time: Option<String>,
    /// Memory per task, in Slurm's syntax (e.g. 8G).
    #[arg(long)]
    pub mem: Option<String>,
    /// CPUs per task.
    #[arg(long)]
    pub cpus_per_task: Option<u32>,
    /// A further argument for sbatch (repeatable), e.g. --sbatch-arg=--account=geo.
    #[arg(long = "sbatch-arg", allow_hyphen_values = true)]
    pub sbatch_args: Vec<String>,
    /// The sparc3d binary as the compute nodes see it (default: this binary).
    #[arg(long)]
    pub sparc3d: Option<PathBuf>,
    /// Task indices allowed per array (default: MaxArraySize from `scontrol show config`).
    #[arg(long)]
    pub max_array_size: Option<u64>,
    /// Also submit shards that a queued task or a live worker already holds.
    #[arg(long)]
    pub force: bool,
    /// Print the script and the sbatch commands; submit nothing.
    #[arg(long)]
    pub dry_run: bool,
    #[command(flatten)]
    pub limits: LimitArgs,
}

/// Runs `sparc3d submit`.
pub fn run(args: Args) -> Result<ExitCode> {
    match args.target {
        Target::Slurm(a) => submit_slurm(a),
    }
}

fn submit_slurm(args: SlurmArgs) -> Result<ExitCode> {
    if args.shards_per_task == 0 {
        bail!("--shards-per-task must be at least 1");
    }
    let root = std::fs::canonicalize(&args.job)
        .with_context(|| format!("job folder {}", args.job.display()))?;
    let job = Job::open(&root)?;
    let queued = submit::queued_shards_now(&root, args.dry_run)?;
    let tally = submit::tally_shards(&job, &queued, args.force)?;
    eprintln!(
        "{}: {} shards, {} complete, {} queued in Slurm, {} held by a live worker, {} to submit",
        root.display(),
        job.file.shards,
        tally.done,
        tally.queued,
        tally.live,
        tally.todo.len()
    );
    if tally.live > 0 {
        eprintln!("note: shards held by a live worker are left to it; submit again once it stops (or --force)");
    }
    if tally.todo.is_empty() {
        return Ok(ExitCode::SUCCESS);
    }
    let plan = build_plan(&args, &root, &tally.todo)?;
    if args.dry_run {
        println!("# {}", plan.script_path.display());
        print!("{}", plan.script);
        for line in plan.command_lines() {
            println!("{line}");
        }
        return Ok(ExitCode::SUCCESS);
    }
    for sub in submit::write_and_submit(&root, &plan)? {
        eprintln!(
            "submitted job {}: {} tasks (--array={}, offset {})",
            sub.job_id, sub.tasks, sub.array, sub.offset
        );
        println!("{}", sub.job_id);
    }
    Ok(ExitCode::SUCCESS)
}

/// The batch script and the arrays covering `todo`, from the command's options.
fn build_plan(args: &SlurmArgs, root: &Path, todo: &[u64]) -> Result<SubmitPlan> {
    let max_array_size = submit::array_size_limit(args.max_array_size, args.dry_run)?;
    let sparc3d = match &args.sparc3d {
        Some(p) => p.clone(),
        None => std::env::current_exe().context("locating the sparc3d binary")?,
    };
    let name = root
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "job".into());
    let script = slurm::batch_script(&ScriptOptions {
        sparc3d,
        job: root.to_path_buf(),
        name: format!("sparc3d-{name}"),
        partition: args.partition.clone(),
        time: args.time.clone(),
        mem: args.mem.clone(),
        cpus_per_task: args.cpus_per_task,
        work_args: args.limits.to_args(),
    });
    let script_path = slurm::slurm_dir(root).join("convert.sbatch");
    let arrays = slurm::plan_arrays(todo, args.shards_per_task, max_array_size)
        .into_iter()
        .map(|p| {
            let a = submit::sbatch_args(
                &p,
                &script_path,
                args.shards_per_task,
                args.max_concurrent,
                &args.sbatch_args,
            );
            (p, a)
        })
        .collect();
    Ok(SubmitPlan {
        script_path,
        script,
        arrays,
        max_concurrent: args.max_concurrent,
        shards_per_task: args.shards_per_task,
        partition: args.partition.clone(),
    })
}
