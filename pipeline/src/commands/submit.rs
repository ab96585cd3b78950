//! `sparc3d submit slurm JOB [--max-concurrent N] [--shards-per-task K] [--partition P]
//! [--dry-run]`: writes `JOB/slurm/convert.sbatch` and submits array jobs covering only the
//! shards that are not complete (by their completion records) and not already queued by an
//! earlier submission, split under the cluster's `MaxArraySize`. Prints the job ids.

use crate::cluster::slurm::{self, ArrayPlan, ScriptOptions, Submission};
use crate::commands::work::LimitArgs;
use anyhow::{bail, Context, Result};
use sparc3d_workers::store::state::{shard_state, Check, ShardState};
use sparc3d_workers::Job;
use std::path::PathBuf;
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
    let previous = slurm::read_submissions(&root)?;
    let queue = if previous.is_empty() {
        Vec::new()
    } else {
        match slurm::squeue() {
            Ok(q) => q,
            Err(e) if args.dry_run => {
                eprintln!("note: cannot read the queue ({e:#}); assuming it is empty");
                Vec::new()
            }
            Err(e) => return Err(e.context("reading the queue to skip shards already queued")),
        }
    };
    let queued = slurm::queued_shards(&previous, &queue);
    let (mut todo, mut held_queued, mut held_live, mut done) = (Vec::new(), 0u64, 0u64, 0u64);
    for shard in 0..job.file.shards {
        match shard_state(&job.layout, shard, job.fingerprint(), Check::Quick)? {
            ShardState::Done(_) => done += 1,
            _ if queued.contains(&shard) && !args.force => held_queued += 1,
            ShardState::Running(_) if !args.force => held_live += 1,
            _ => todo.push(shard),
        }
    }
    eprintln!(
        "{}: {} shards, {done} complete, {held_queued} queued in Slurm, {held_live} held by a live worker, {} to submit",
        root.display(),
        job.file.shards,
        todo.len()
    );
    if held_live > 0 {
        eprintln!("note: shards held by a live worker are left to it; submit again once it stops (or --force)");
    }
    if todo.is_empty() {
        return Ok(ExitCode::SUCCESS);
    }
    let max_array_size = match args.max_array_size {
        Some(n) => n.max(1),
        None => match slurm::max_array_size() {
            Ok(n) => n,
            Err(e) if args.dry_run => {
                eprintln!(
                    "note: {e:#}; assuming MaxArraySize={}",
                    slurm::DEFAULT_MAX_ARRAY_SIZE
                );
                slurm::DEFAULT_MAX_ARRAY_SIZE
            }
            Err(e) => return Err(e),
        },
    };
    let plans = slurm::plan_arrays(&todo, args.shards_per_task, max_array_size);
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
        job: root.clone(),
        name: format!("sparc3d-{name}"),
        partition: args.partition.clone(),
        time: args.time.clone(),
        mem: args.mem.clone(),
        cpus_per_task: args.cpus_per_task,
        work_args: args.limits.to_args(),
    });
    let dir = slurm::slurm_dir(&root);
    let script_path = dir.join("convert.sbatch");
    let sbatch_args = |p: &ArrayPlan| {
        let mut a = vec![format!(
            "--array={}",
            slurm::array_spec(&p.tasks, args.max_concurrent)
        )];
        a.extend(args.sbatch_args.iter().cloned());
        a.push(script_path.to_string_lossy().into_owned());
        a.extend([
            "--shards-per-task".into(),
            args.shards_per_task.to_string(),
            "--offset".into(),
            p.offset.to_string(),
        ]);
        a
    };
    if args.dry_run {
        println!("# {}", script_path.display());
        print!("{script}");
        for p in &plans {
            let words: Vec<String> = sbatch_args(p)
                .iter()
                .map(|w| slurm::shell_quote(w))
                .collect();
            println!("sbatch --parsable {}", words.join(" "));
        }
        return Ok(ExitCode::SUCCESS);
    }
    std::fs::create_dir_all(dir.join("logs"))
        .with_context(|| format!("creating {}", dir.join("logs").display()))?;
    let tmp = dir.join(".convert.sbatch.tmp");
    std::fs::write(&tmp, &script).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, &script_path)
        .with_context(|| format!("renaming {} to {}", tmp.display(), script_path.display()))?;
    for p in &plans {
        let a = sbatch_args(p);
        let id = slurm::sbatch(&a)?;
        let sub = Submission {
            job_id: id.clone(),
            submitted_at: sparc3d_workers::now(),
            array: slurm::array_spec(&p.tasks, args.max_concurrent),
            offset: p.offset,
            shards_per_task: args.shards_per_task,
            tasks: p.tasks.len() as u64,
            partition: args.partition.clone(),
        };
        slurm::append_submission(&root, &sub)
            .with_context(|| format!("recording Slurm job {id} (it is submitted)"))?;
        eprintln!(
            "submitted job {id}: {} tasks (--array={}, offset {})",
            sub.tasks, sub.array, sub.offset
        );
        println!("{id}");
    }
    Ok(ExitCode::SUCCESS)
}
