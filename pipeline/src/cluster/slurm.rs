//! Slurm: which array tasks to submit for the unfinished shards of a job, the batch script,
//! thin wrappers around `sbatch`, `squeue` and `scontrol`, and the record of what was
//! submitted (`JOB/slurm/submissions.jsonl`), read back by `sparc3d status`.
//!
//! Array task `T` of a submission with offset `O` and `K` shards per task runs
//! `sparc3d work JOB --array --shards-per-task K --offset O`, i.e. shards `O + T·K …
//! O + T·K + K − 1`. Slurm refuses task indices at or above `MaxArraySize`, so the tasks are
//! split into several arrays, each with its own offset.

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Slurm's default `MaxArraySize` (task indices 0 … 1000).
pub const DEFAULT_MAX_ARRAY_SIZE: u64 = 1001;

/// One array to submit: task `t` covers shards `offset + t·K …`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ArrayPlan {
    /// First shard of task 0.
    pub offset: u64,
    /// Task indices, ascending, each below `MaxArraySize`.
    pub tasks: Vec<u64>,
}

/// Plans the arrays that cover `shards` (any order, duplicates allowed) with `k` shards per
/// task, every task index below `max_array_size`. A task may also cover finished shards of
/// its group; `work` skips those after reading their completion records.
pub fn plan_arrays(shards: &[u64], k: u64, max_array_size: u64) -> Vec<ArrayPlan> {
    let k = k.max(1);
    let max = max_array_size.max(1);
    let groups: BTreeSet<u64> = shards.iter().map(|s| s / k).collect();
    let mut plans: Vec<ArrayPlan> = Vec::new();
    let mut first = 0;
    for g in groups {
        match plans.last_mut() {
            Some(p) if g - first < max => p.tasks.push(g - first),
            _ => {
                first = g;
                plans.push(ArrayPlan {
                    offset: g * k,
                    tasks: vec![0],
                });
            }
        }
    }
    plans
}

/// The `--array` value for ascending task indices: ranges joined by commas, then `%N` when
/// at most `max_concurrent` tasks may run at once (e.g. `0-3,7,9-12%4`).
pub fn array_spec(tasks: &[u64], max_concurrent: Option<u32>) -> String {
    let mut parts = Vec::new();
    let mut i = 0;
    while i < tasks.len() {
        let start = tasks[i];
        let mut end = start;
        while i + 1 < tasks.len() && tasks[i + 1] == end + 1 {
            i += 1;
            end = tasks[i];
        }
        parts.push(if start == end {
            start.to_string()
        } else {
            format!("{start}-{end}")
        });
        i += 1;
    }
    let mut spec = parts.join(",");
    if let Some(n) = max_concurrent.filter(|n| *n > 0) {
        spec.push_str(&format!("%{n}"));
    }
    spec
}

/// `MaxArraySize` from the text of `scontrol show config` (a line `MaxArraySize = 1001`).
pub fn parse_max_array_size(config: &str) -> Option<u64> {
    config.lines().find_map(|line| {
        let (key, value) = line.split_once('=')?;
        (key.trim() == "MaxArraySize")
            .then(|| value.trim().parse().ok())
            .flatten()
    })
}

/// The job id printed by `sbatch --parsable` (`123` or `123;cluster`).
pub fn parse_sbatch_id(stdout: &str) -> Option<String> {
    let id = stdout.trim().split(';').next()?.trim();
    (!id.is_empty() && id.chars().all(|c| c.is_ascii_digit())).then(|| id.to_string())
}

/// One array task in the queue, from `squeue -h -r -o '%F|%K|%T'`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct QueuedTask {
    /// The array's job id.
    pub job_id: String,
    /// The task index, if the line is an array task.
    pub task: Option<u64>,
    /// Slurm's state name (PENDING, RUNNING, COMPLETING, …).
    pub state: String,
}

/// The output format [`parse_squeue`] reads.
pub const SQUEUE_FORMAT: &str = "%F|%K|%T";

/// Parses `squeue -h -r -o '%F|%K|%T'`; lines that do not fit are skipped.
pub fn parse_squeue(stdout: &str) -> Vec<QueuedTask> {
    stdout
        .lines()
        .filter_map(|line| {
            let mut f = line.trim().split('|');
            let job_id = f.next()?.trim().to_string();
            let task = f.next()?.trim().parse().ok();
            let state = f.next()?.trim().to_string();
            (!job_id.is_empty()).then_some(QueuedTask {
                job_id,
                task,
                state,
            })
        })
        .collect()
}

/// What `sparc3d submit slurm` submitted: one line of `JOB/slurm/submissions.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Submission {
    /// Slurm's job id of the array.
    pub job_id: String,
    /// Unix time of the submission.
    pub submitted_at: f64,
    /// The `--array` value.
    pub array: String,
    /// First shard of task 0.
    pub offset: u64,
    /// Shards per task.
    pub shards_per_task: u64,
    /// Tasks in the array.
    pub tasks: u64,
    /// Partition, if one was given.
    #[serde(default)]
    pub partition: Option<String>,
}

impl Submission {
    /// The shards task `task` of this array works on.
    pub fn task_shards(&self, task: u64) -> std::ops::Range<u64> {
        let k = self.shards_per_task.max(1);
        let first = self.offset + task * k;
        first..first + k
    }
}

/// `JOB/slurm/`: the batch script, the submissions and the task logs.
pub fn slurm_dir(job: &Path) -> PathBuf {
    job.join("slurm")
}

/// `JOB/slurm/submissions.jsonl`.
pub fn submissions_file(job: &Path) -> PathBuf {
    slurm_dir(job).join("submissions.jsonl")
}

/// Reads the job's submissions (none if the file does not exist).
pub fn read_submissions(job: &Path) -> Result<Vec<Submission>> {
    let path = submissions_file(job);
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
    };
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(n, l)| {
            serde_json::from_str(l)
                .with_context(|| format!("{} line {}: not a submission", path.display(), n + 1))
        })
        .collect()
}

/// Appends a submission to `JOB/slurm/submissions.jsonl` (fsynced).
pub fn append_submission(job: &Path, s: &Submission) -> Result<()> {
    let path = submissions_file(job);
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .with_context(|| format!("opening {}", path.display()))?;
    let line = serde_json::to_string(s)?;
    writeln!(f, "{line}").with_context(|| format!("writing {}", path.display()))?;
    f.sync_all()
        .with_context(|| format!("syncing {}", path.display()))
}

/// Quotes a word for a POSIX shell.
pub fn shell_quote(s: &str) -> String {
    if !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "/._-+=:,@%".contains(c))
    {
        return s.to_string();
    }
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// What goes into the batch script.
#[derive(Debug, Clone, Default)]
pub struct ScriptOptions {
    /// The sparc3d binary, as the compute nodes see it.
    pub sparc3d: PathBuf,
    /// The job folder (absolute, on the shared filesystem).
    pub job: PathBuf,
    /// `--job-name`.
    pub name: String,
    /// `--partition`.
    pub partition: Option<String>,
    /// `--time` (Slurm syntax, e.g. `4:00:00`).
    pub time: Option<String>,
    /// `--mem` (Slurm syntax, e.g. `8G`).
    pub mem: Option<String>,
    /// `--cpus-per-task`.
    pub cpus_per_task: Option<u32>,
    /// Further arguments of `sparc3d work` (limits).
    pub work_args: Vec<String>,
}

/// The batch script: one array task runs `sparc3d work JOB --array` with the arguments that
/// `sbatch` passes after the script (`--shards-per-task K --offset O`).
pub fn batch_script(o: &ScriptOptions) -> String {
    let logs = slurm_dir(&o.job).join("logs");
    let mut s = String::from("#!/bin/bash\n");
    s.push_str(
        "# Written by `sparc3d submit slurm`; submitted as an array job, one task = K shards.\n",
    );
    s.push_str(&format!("#SBATCH --job-name={}\n", o.name));
    s.push_str(&format!("#SBATCH --output={}/%A_%a.out\n", logs.display()));
    s.push_str("#SBATCH --open-mode=append\n");
    s.push_str("#SBATCH --requeue\n");
    if let Some(p) = &o.partition {
        s.push_str(&format!("#SBATCH --partition={p}\n"));
    }
    if let Some(t) = &o.time {
        s.push_str(&format!("#SBATCH --time={t}\n"));
    }
    if let Some(m) = &o.mem {
        s.push_str(&format!("#SBATCH --mem={m}\n"));
    }
    if let Some(c) = o.cpus_per_task {
        s.push_str(&format!("#SBATCH --cpus-per-task={c}\n"));
    }
    s.push_str("set -eu\n");
    s.push_str("echo \"task ${SLURM_ARRAY_JOB_ID:-?}_${SLURM_ARRAY_TASK_ID:-?} on $(hostname) at $(date -Is): work $*\" >&2\n");
    let mut cmd = vec![
        shell_quote(&o.sparc3d.to_string_lossy()),
        "work".to_string(),
        shell_quote(&o.job.to_string_lossy()),
        "--array".to_string(),
        "\"$@\"".to_string(),
    ];
    cmd.extend(o.work_args.iter().map(|a| shell_quote(a)));
    s.push_str(&format!("exec {}\n", cmd.join(" ")));
    s
}

fn run_tool(program: &str, args: &[String]) -> Result<String> {
    let out = Command::new(program)
        .args(args)
        .output()
        .with_context(|| format!("running {program} (is Slurm installed and on PATH?)"))?;
    if !out.status.success() {
        bail!(
            "{program} {} failed ({}): {}",
            args.join(" "),
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// `MaxArraySize` of the cluster, from `scontrol show config`.
pub fn max_array_size() -> Result<u64> {
    let text = run_tool("scontrol", &["show".into(), "config".into()])?;
    Ok(parse_max_array_size(&text).unwrap_or(DEFAULT_MAX_ARRAY_SIZE))
}

/// Runs `sbatch --parsable ARGS` and returns the job id.
pub fn sbatch(args: &[String]) -> Result<String> {
    let mut a = vec!["--parsable".to_string()];
    a.extend_from_slice(args);
    let out = run_tool("sbatch", &a)?;
    parse_sbatch_id(&out).with_context(|| format!("sbatch printed {:?}, not a job id", out.trim()))
}

/// This user's array tasks in the queue, one line per task (`squeue -h -r --me`).
pub fn squeue() -> Result<Vec<QueuedTask>> {
    let out = run_tool(
        "squeue",
        &[
            "-h".into(),
            "-r".into(),
            "--me".into(),
            "-o".into(),
            SQUEUE_FORMAT.into(),
        ],
    )?;
    Ok(parse_squeue(&out))
}

/// Tasks of `subs` still in the queue, per array job id: (pending, running or finishing).
pub fn queue_counts(subs: &[Submission], queue: &[QueuedTask]) -> BTreeMap<String, (u64, u64)> {
    let ids: BTreeSet<&str> = subs.iter().map(|s| s.job_id.as_str()).collect();
    let mut counts: BTreeMap<String, (u64, u64)> = BTreeMap::new();
    for q in queue.iter().filter(|q| ids.contains(q.job_id.as_str())) {
        let c = counts.entry(q.job_id.clone()).or_default();
        if q.state == "PENDING" || q.state == "REQUEUED" || q.state == "REQUEUE_HOLD" {
            c.0 += 1;
        } else {
            c.1 += 1;
        }
    }
    counts
}

/// Shards that tasks of `subs` still in the queue (pending or running) will work on.
pub fn queued_shards(subs: &[Submission], queue: &[QueuedTask]) -> BTreeSet<u64> {
    let by_id: BTreeMap<&str, &Submission> = subs.iter().map(|s| (s.job_id.as_str(), s)).collect();
    let mut shards = BTreeSet::new();
    for q in queue {
        if let (Some(sub), Some(task)) = (by_id.get(q.job_id.as_str()), q.task) {
            shards.extend(sub.task_shards(task));
        }
    }
    shards
}

/// The Slurm section of `sparc3d status JOB`: submitted arrays and their tasks in the queue.
/// Prints nothing for a job never submitted to Slurm; problems are printed, not returned.
pub fn print_status(job: &Path) {
    let subs = match read_submissions(job) {
        Ok(s) if s.is_empty() => return,
        Ok(s) => s,
        Err(e) => {
            println!("slurm:  {e:#}");
            return;
        }
    };
    let queue = squeue();
    let counts = match &queue {
        Ok(q) => queue_counts(&subs, q),
        Err(_) => BTreeMap::new(),
    };
    let (pending, running) = counts
        .values()
        .fold((0, 0), |(p, r), (a, b)| (p + a, r + b));
    let ids: Vec<&str> = subs.iter().map(|s| s.job_id.as_str()).collect();
    match &queue {
        Ok(_) => println!(
            "slurm:  {} array(s) submitted; {pending} task(s) pending, {running} running",
            subs.len()
        ),
        Err(e) => println!(
            "slurm:  {} array(s) submitted; queue unknown: {e:#}",
            subs.len()
        ),
    }
    let now = sparc3d_workers::clock::now();
    let shown = subs.len().saturating_sub(10);
    if shown > 0 {
        println!("  … {shown} older, all ids: {}", ids.join(","));
    }
    for s in &subs[shown..] {
        let (p, r) = counts.get(&s.job_id).copied().unwrap_or_default();
        let queue_text = if p + r == 0 {
            "none in queue".to_string()
        } else {
            format!("{p} pending, {r} running")
        };
        println!(
            "  job {:>8}  array {}  offset {}  K={}  {} ago  {queue_text}",
            s.job_id,
            s.array,
            s.offset,
            s.shards_per_task,
            crate::util::units::format_seconds((now - s.submitted_at).max(0.0)),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plans_one_array_per_max_array_size() {
        let shards: Vec<u64> = (0..10).collect();
        assert_eq!(
            plan_arrays(&shards, 1, 1001),
            vec![ArrayPlan {
                offset: 0,
                tasks: shards.clone()
            }]
        );
        let p = plan_arrays(&shards, 1, 4);
        assert_eq!(p.len(), 3);
        assert_eq!(
            p[0],
            ArrayPlan {
                offset: 0,
                tasks: vec![0, 1, 2, 3]
            }
        );
        assert_eq!(
            p[1],
            ArrayPlan {
                offset: 4,
                tasks: vec![0, 1, 2, 3]
            }
        );
        assert_eq!(
            p[2],
            ArrayPlan {
                offset: 8,
                tasks: vec![0, 1]
            }
        );
    }

    #[test]
    fn plans_groups_of_k_and_skips_gaps() {
        // shards 3, 4, 5, 11 with K=2: groups 1, 2, 5 → the array starts at group 1 (shard 2)
        let p = plan_arrays(&[11, 3, 4, 5, 4], 2, 1001);
        assert_eq!(
            p,
            vec![ArrayPlan {
                offset: 2,
                tasks: vec![0, 1, 4]
            }]
        );
        // a late shard starts its own array at its group, not at 0
        let p = plan_arrays(&[5000], 1, 1001);
        assert_eq!(
            p,
            vec![ArrayPlan {
                offset: 5000,
                tasks: vec![0]
            }]
        );
        // every planned shard is covered exactly by the tasks
        let shards = [0u64, 7, 8, 9, 2000, 2001, 4100];
        for (k, max) in [(1, 3), (3, 2), (7, 1001), (2, 1)] {
            let mut covered = BTreeSet::new();
            for p in plan_arrays(&shards, k, max) {
                for t in &p.tasks {
                    assert!(*t < max);
                    covered.extend(p.offset + t * k..p.offset + t * k + k);
                }
            }
            assert!(
                shards.iter().all(|s| covered.contains(s)),
                "k={k} max={max}"
            );
        }
        assert!(plan_arrays(&[], 1, 1001).is_empty());
    }

    #[test]
    fn array_specs_compress_ranges_and_throttle() {
        assert_eq!(array_spec(&[0, 1, 2, 3], None), "0-3");
        assert_eq!(array_spec(&[0, 1, 2, 3, 7, 9, 10], Some(4)), "0-3,7,9-10%4");
        assert_eq!(array_spec(&[5], Some(0)), "5");
    }

    #[test]
    fn parses_scontrol_sbatch_and_squeue() {
        let conf =
            "Configuration data as of 2024\nMaxArraySize            = 40001\nMaxJobCount = 10000\n";
        assert_eq!(parse_max_array_size(conf), Some(40001));
        assert_eq!(parse_max_array_size("MaxJobCount = 1"), None);
        assert_eq!(parse_sbatch_id("123\n").as_deref(), Some("123"));
        assert_eq!(parse_sbatch_id("77;ci\n").as_deref(), Some("77"));
        assert_eq!(parse_sbatch_id("sbatch: error"), None);
        let q = parse_squeue("12|3|RUNNING\n12|4|PENDING\n13|N/A|PENDING\ngarbage\n");
        assert_eq!(q.len(), 3);
        assert_eq!(q[0].task, Some(3));
        assert_eq!(q[2].task, None);
    }

    #[test]
    fn queued_tasks_map_back_to_shards() {
        let sub = |id: &str, offset, k| Submission {
            job_id: id.into(),
            submitted_at: 0.0,
            array: String::new(),
            offset,
            shards_per_task: k,
            tasks: 0,
            partition: None,
        };
        let subs = [sub("12", 0, 2), sub("13", 100, 1)];
        let q = parse_squeue("12|3|RUNNING\n13|4|PENDING\n99|0|PENDING\n");
        let shards: Vec<u64> = queued_shards(&subs, &q).into_iter().collect();
        assert_eq!(shards, vec![6, 7, 104]);
        let c = queue_counts(&subs, &q);
        assert_eq!(c.get("12"), Some(&(0, 1)));
        assert_eq!(c.get("13"), Some(&(1, 0)));
        assert!(!c.contains_key("99"));
    }

    #[test]
    fn batch_script_quotes_paths_and_passes_task_args() {
        let s = batch_script(&ScriptOptions {
            sparc3d: "/opt/sparc3d/bin/sparc3d".into(),
            job: "/shared/jobs/it's here".into(),
            name: "sparc3d-x".into(),
            partition: Some("cpu".into()),
            time: Some("2:00:00".into()),
            mem: None,
            cpus_per_task: Some(2),
            work_args: vec!["--item-timeout".into(), "90".into()],
        });
        assert!(s.starts_with("#!/bin/bash\n"));
        assert!(s.contains("#SBATCH --partition=cpu\n"));
        assert!(s.contains("#SBATCH --cpus-per-task=2\n"));
        assert!(!s.contains("--mem"));
        assert!(s.contains(
            "exec /opt/sparc3d/bin/sparc3d work '/shared/jobs/it'\\''s here' --array \"$@\" --item-timeout 90\n"
        ));
    }
}
