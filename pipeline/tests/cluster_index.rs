//! Cluster entry points without a cluster: `work --array` takes its shard from a Kubernetes
//! indexed Job's `JOB_COMPLETION_INDEX` (or Slurm's `SLURM_ARRAY_TASK_ID`), and
//! `submit slurm --dry-run` plans arrays for the unfinished shards only.

mod common;

use common::{ok_env as ok, s, sparc3d_env as sparc3d};
use std::path::{Path, PathBuf};

/// A job over the repository's five example meshes: 3 shards of 2 items at resolution 32.
fn example_job(dir: &Path) -> PathBuf {
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    let manifest = dir.join("manifest.jsonl");
    let job = dir.join("job");
    ok(
        &["manifest", "build", s(&examples), "-o", s(&manifest)],
        &[],
    );
    ok(
        &[
            "init",
            s(&job),
            "--manifest",
            s(&manifest),
            "--resolution",
            "32",
            "--shard-size",
            "2",
        ],
        &[],
    );
    job
}

fn complete(job: &Path, shard: u64) -> bool {
    job.join(format!("shards/part-{shard:05}.complete.json"))
        .exists()
}

#[test]
fn indexed_job_completion_index_selects_the_shard() {
    let dir = tempfile::tempdir().expect("temp dir");
    let job = example_job(dir.path());
    // a Kubernetes indexed Job: pod 1 of 3 runs `sparc3d work JOB --array`
    ok(
        &["work", s(&job), "--array"],
        &[("JOB_COMPLETION_INDEX", "1")],
    );
    assert!(complete(&job, 1));
    assert!(!complete(&job, 0) && !complete(&job, 2));
    // a retried pod of the same index finds the shard done and succeeds
    ok(
        &["work", s(&job), "--array"],
        &[("JOB_COMPLETION_INDEX", "1")],
    );
    // an index past the last shard (e.g. completions rounded up) has nothing to do
    ok(
        &["work", s(&job), "--array", "--shards-per-task", "2"],
        &[("JOB_COMPLETION_INDEX", "5")],
    );
    assert!(!complete(&job, 0) && !complete(&job, 2));
    // --offset shifts the index: index 0 with offset 2 is shard 2
    ok(
        &["work", s(&job), "--array", "--offset", "2"],
        &[("JOB_COMPLETION_INDEX", "0")],
    );
    assert!(complete(&job, 2) && !complete(&job, 0));

    // submit slurm --dry-run: only shard 0 is left; nothing is submitted or recorded
    let out = ok(
        &[
            "submit",
            "slurm",
            s(&job),
            "--dry-run",
            "--max-concurrent",
            "3",
            "--max-array-size",
            "4",
        ],
        &[],
    );
    let sbatch: Vec<&str> = out.lines().filter(|l| l.starts_with("sbatch ")).collect();
    assert_eq!(sbatch.len(), 1, "{out}");
    assert!(
        sbatch[0].contains("--array=0%3") && sbatch[0].ends_with("--shards-per-task 1 --offset 0"),
        "{out}"
    );
    assert!(
        out.contains(" work ") && out.contains("--array \"$@\""),
        "{out}"
    );
    assert!(!job.join("slurm/submissions.jsonl").exists());
}

#[test]
fn dry_run_splits_arrays_under_max_array_size() {
    let dir = tempfile::tempdir().expect("temp dir");
    let job = example_job(dir.path());
    let out = ok(
        &[
            "submit",
            "slurm",
            s(&job),
            "--dry-run",
            "--max-array-size",
            "2",
            "--partition",
            "cpu",
        ],
        &[],
    );
    let sbatch: Vec<&str> = out.lines().filter(|l| l.starts_with("sbatch ")).collect();
    assert_eq!(sbatch.len(), 2, "{out}");
    assert!(sbatch[0].contains("--array=0-1 ") && sbatch[0].ends_with("--offset 0"));
    assert!(sbatch[1].contains("--array=0 ") && sbatch[1].ends_with("--offset 2"));
    assert!(out.contains("#SBATCH --partition=cpu"), "{out}");
}

#[test]
fn bad_task_index_is_an_error_naming_the_variable() {
    let dir = tempfile::tempdir().expect("temp dir");
    let job = example_job(dir.path());
    let out = sparc3d(
        &["work", s(&job), "--array"],
        &[("JOB_COMPLETION_INDEX", "one")],
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("JOB_COMPLETION_INDEX"), "{err}");
    let out = sparc3d(&["work", s(&job), "--array"], &[]);
    assert!(!out.status.success());
}
