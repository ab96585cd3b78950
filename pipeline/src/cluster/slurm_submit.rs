//! The steps of `sparc3d submit slurm`, apart from its argument parsing and printing: which
//! shards still need a task (finished ones and those already queued or held are left out),
//! the cluster's array limit, and writing the batch script before each array is submitted
//! and recorded.

use super::slurm::{self, ArrayPlan, Submission};
use anyhow::{Context, Result};
use sparc3d_workers::store::state::{shard_state, Check, ShardState};
use sparc3d_workers::Job;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The shards of a job sorted by what a submission does with them.
#[derive(Debug, Default, PartialEq, Eq)]
pub struct ShardTally {
    /// Shards to submit, ascending.
    pub todo: Vec<u64>,
    /// Shards complete by their completion records.
    pub done: u64,
    /// Shards a queued task of an earlier submission covers.
    pub queued: u64,
    /// Shards a live worker holds the lease of.
    pub live: u64,
}

/// The shards that earlier submissions still have queued in Slurm (none when nothing was
/// submitted before). On a dry run an unreadable queue is taken as empty, with a note.
pub fn queued_shards_now(root: &Path, dry_run: bool) -> Result<BTreeSet<u64>> {
    let previous = slurm::read_submissions(root)?;
    if previous.is_empty() {
        return Ok(BTreeSet::new());
    }
    let queue = match slurm::squeue() {
        Ok(q) => q,
        Err(e) if dry_run => {
            eprintln!("note: cannot read the queue ({e:#}); assuming it is empty");
            Vec::new()
        }
        Err(e) => return Err(e.context("reading the queue to skip shards already queued")),
    };
    Ok(slurm::queued_shards(&previous, &queue))
}

/// Sorts every shard of `job`: complete, queued, held by a live worker, or to submit (with
/// `force`, queued and held shards are submitted again).
pub fn tally_shards(job: &Job, queued: &BTreeSet<u64>, force: bool) -> Result<ShardTally> {
    let mut t = ShardTally::default();
    for shard in 0..job.file.shards {
        match shard_state(&job.layout, shard, job.fingerprint(), Check::Quick)? {
            ShardState::Done(_) => t.done += 1,
            _ if queued.contains(&shard) && !force => t.queued += 1,
            ShardState::Running(_) if !force => t.live += 1,
            _ => t.todo.push(shard),
        }
    }
    Ok(t)
}

/// The array size limit: the one given, else `MaxArraySize` from `scontrol` (Slurm's default
/// on a dry run where `scontrol` cannot answer).
pub fn array_size_limit(given: Option<u64>, dry_run: bool) -> Result<u64> {
    if let Some(n) = given {
        return Ok(n.max(1));
    }
    match slurm::max_array_size() {
        Ok(n) => Ok(n),
        Err(e) if dry_run => {
            eprintln!(
                "note: {e:#}; assuming MaxArraySize={}",
                slurm::DEFAULT_MAX_ARRAY_SIZE
            );
            Ok(slurm::DEFAULT_MAX_ARRAY_SIZE)
        }
        Err(e) => Err(e),
    }
}

/// One submission to make: the batch script and, per array, its plan and sbatch arguments.
#[derive(Debug)]
pub struct SubmitPlan {
    /// Where the batch script goes (`JOB/slurm/convert.sbatch`).
    pub script_path: PathBuf,
    /// The batch script's text.
    pub script: String,
    /// Each array with the arguments `sbatch --parsable` gets for it.
    pub arrays: Vec<(ArrayPlan, Vec<String>)>,
    /// The `--array` throttle (`%N`).
    pub max_concurrent: Option<u32>,
    /// Shards per array task.
    pub shards_per_task: u64,
    /// The partition, recorded with each submission.
    pub partition: Option<String>,
}

impl SubmitPlan {
    /// The sbatch command lines, shell-quoted, as a dry run prints them.
    pub fn command_lines(&self) -> Vec<String> {
        self.arrays
            .iter()
            .map(|(_, args)| {
                let words: Vec<String> = args.iter().map(|w| slurm::shell_quote(w)).collect();
                format!("sbatch --parsable {}", words.join(" "))
            })
            .collect()
    }
}

/// The sbatch arguments of one array: `--array`, the user's extra arguments, the script and
/// the `work` arguments that place task 0 at the array's offset.
pub fn sbatch_args(
    plan: &ArrayPlan,
    script_path: &Path,
    shards_per_task: u64,
    max_concurrent: Option<u32>,
    extra: &[String],
) -> Vec<String> {
    let mut a = vec![format!(
        "--array={}",
        slurm::array_spec(&plan.tasks, max_concurrent)
    )];
    a.extend(extra.iter().cloned());
    a.push(script_path.to_string_lossy().into_owned());
    a.extend([
        "--shards-per-task".into(),
        shards_per_task.to_string(),
        "--offset".into(),
        plan.offset.to_string(),
    ]);
    a
}

/// Writes the batch script (atomically), then submits each array and appends it to
/// `JOB/slurm/submissions.jsonl` as soon as Slurm accepted it. Returns the submissions made.
pub fn write_and_submit(root: &Path, plan: &SubmitPlan) -> Result<Vec<Submission>> {
    let dir = slurm::slurm_dir(root);
    std::fs::create_dir_all(dir.join("logs"))
        .with_context(|| format!("creating {}", dir.join("logs").display()))?;
    let tmp = dir.join(".convert.sbatch.tmp");
    std::fs::write(&tmp, &plan.script).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, &plan.script_path).with_context(|| {
        format!(
            "renaming {} to {}",
            tmp.display(),
            plan.script_path.display()
        )
    })?;
    let mut made = Vec::new();
    for (array, args) in &plan.arrays {
        let id = slurm::sbatch(args)?;
        let sub = Submission {
            job_id: id.clone(),
            submitted_at: sparc3d_workers::clock::now(),
            array: slurm::array_spec(&array.tasks, plan.max_concurrent),
            offset: array.offset,
            shards_per_task: plan.shards_per_task,
            tasks: array.tasks.len() as u64,
            partition: plan.partition.clone(),
        };
        slurm::append_submission(root, &sub)
            .with_context(|| format!("recording Slurm job {id} (it is submitted)"))?;
        made.push(sub);
    }
    Ok(made)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sbatch_args_place_the_script_between_slurm_and_work_arguments() {
        let plan = ArrayPlan {
            offset: 1001,
            tasks: vec![0, 1, 2, 5],
        };
        let a = sbatch_args(
            &plan,
            Path::new("/j/slurm/convert.sbatch"),
            2,
            Some(4),
            &["--account=geo".to_string()],
        );
        assert_eq!(a[0], "--array=0-2,5%4");
        assert_eq!(a[1], "--account=geo");
        assert_eq!(a[2], "/j/slurm/convert.sbatch");
        assert_eq!(&a[3..], ["--shards-per-task", "2", "--offset", "1001"]);
    }
}
