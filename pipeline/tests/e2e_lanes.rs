//! End to end (issue 46): a job of fewer shards than workers keeps every worker converting,
//! and writes what one worker writes, also when stopped and killed mid-shard and resumed.

mod common;

use common::*;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Two jobs of the test corpus in one shard each (`--shard-size 256`), at 96³.
fn one_shard_jobs(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let meshes = corpus(dir);
    let manifest = dir.join("m.jsonl");
    ok(&["manifest", "build", s(&meshes), "-o", s(&manifest)]);
    let (a, b) = (dir.join("a"), dir.join("b"));
    for job in [&a, &b] {
        ok(&[
            "init",
            s(job),
            "--manifest",
            s(&manifest),
            "--resolution",
            "96",
        ]);
    }
    (a, b)
}

/// Runs `run JOB --workers N`, asserting success; its stderr.
fn run_ok(job: &Path, workers: &str) -> String {
    let out = sparc3d(&["run", s(job), "--workers", workers]);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "run --workers {workers}: {err}");
    err
}

fn digest(job: &Path) -> String {
    inspect(job)["content_digest"]
        .as_str()
        .unwrap_or_default()
        .to_string()
}

#[test]
fn one_shard_on_two_workers_converts_two_items_at_once_and_writes_what_one_worker_writes() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let (a, b) = one_shard_jobs(tmp.path());
    assert_eq!(inspect_shards(&a), 1);
    let one = run_ok(&a, "1");
    assert!(one.contains("(most items at once: 1)"), "{one}");
    let two = run_ok(&b, "2");
    assert!(two.contains("1 shards left, 2 workers"), "{two}");
    assert!(two.contains("(most items at once: 2)"), "{two}");
    assert_each_item_once(&b);
    assert_eq!(digest(&a), digest(&b));
    assert_eq!(all_rows(&a), all_rows(&b));
}

fn inspect_shards(job: &Path) -> u64 {
    let v: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(job.join("job.json")).unwrap_or_else(|e| panic!("{e}")),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    v["shards"].as_u64().unwrap_or_default()
}

fn spawn_run(job: &Path, workers: &str) -> Child {
    Command::new(bin())
        .args(["run", s(job), "--workers", workers])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap_or_else(|e| panic!("{e}"))
}

/// Items with a row in the shard's journals, from `status --json`.
fn finished(job: &Path) -> u64 {
    let v = status(job);
    v["ok"].as_u64().unwrap_or(0) + v["failed"].as_u64().unwrap_or(0)
}

/// Waits until at least `n` items of `job` finished (or the run ended); true if they did.
fn wait_for_items(job: &Path, run: &mut Child, n: u64) -> bool {
    let deadline = Instant::now() + Duration::from_secs(120);
    while Instant::now() < deadline {
        if finished(job) >= n {
            return true;
        }
        if matches!(run.try_wait(), Ok(Some(_))) {
            return false;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    false
}

#[test]
fn a_shard_stopped_and_killed_mid_way_on_three_workers_resumes_to_the_same_digest() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let (a, b) = one_shard_jobs(tmp.path());
    run_ok(&a, "1");
    // A clean stop (SIGTERM) with three items converting: they are journalled as aborted.
    let mut run = spawn_run(&b, "3");
    assert!(wait_for_items(&b, &mut run, 3), "the run ended too early");
    // SAFETY: a signal to a child of this test.
    unsafe {
        libc::kill(run.id() as i32, libc::SIGTERM);
    }
    let stopped = run.wait().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(stopped.code(), Some(143), "stopped by SIGTERM");
    let after_stop = finished(&b);
    // Then the whole tree killed at once, mid-shard: the items in flight become interrupted
    // attempts, tried again.
    let mut run = spawn_run(&b, "3");
    if wait_for_items(&b, &mut run, after_stop + 3) {
        let mut victims = descendants(run.id());
        victims.push(run.id());
        for pid in victims {
            kill9(pid);
        }
    }
    let _ = run.wait();
    run_ok(&b, "2");
    assert_each_item_once(&b);
    assert_eq!(digest(&a), digest(&b));
}

/// Issue 64 item 5: `run --workers 10000` on a 12-item job takes at most as many workers as
/// there are items, says so on stderr, and converts the job (before: thousands of lanes, a
/// stall).
#[test]
fn workers_asked_past_the_items_are_taken_at_most_as_many_as_there_are_items() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let manifest = twelve_mesh_manifest(dir.path());
    let job = dir.path().join("job");
    ok(&[
        "init",
        s(&job),
        "--manifest",
        s(&manifest),
        "--resolution",
        "16",
    ]);
    let run = sparc3d(&["run", s(&job), "--workers", "10000"]);
    let said = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{said}");
    assert!(said.contains("(10000 asked: 12 items left"), "{said}");
    // The manifest holds one item that fails by design: every item has its row.
    let st = status(&job);
    assert_eq!(
        st["ok"].as_u64().unwrap_or(0) + st["failed"].as_u64().unwrap_or(0),
        12,
        "{st}"
    );
}

/// Issue 64 item 5: `work --threads 4096` takes the machine's cores, says so, and writes the
/// shard `--threads 1` writes (before: 4,096 threads in each item worker).
#[test]
fn threads_asked_past_the_cores_are_taken_as_the_cores_and_the_shard_is_the_same() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let manifest = twelve_mesh_manifest(dir.path());
    let jobs = [dir.path().join("a"), dir.path().join("b")];
    for (job, threads) in jobs.iter().zip(["1", "4096"]) {
        ok(&[
            "init",
            s(job),
            "--manifest",
            s(&manifest),
            "--resolution",
            "16",
        ]);
        let work = sparc3d(&["work", s(job), "--shard-index", "0", "--threads", threads]);
        let said = String::from_utf8_lossy(&work.stderr);
        assert!(work.status.success(), "{said}");
        let capped = said.contains("--threads 4096 taken as");
        assert_eq!(capped, threads == "4096", "{said}");
    }
    assert_eq!(digest(&jobs[0]), digest(&jobs[1]));
}
