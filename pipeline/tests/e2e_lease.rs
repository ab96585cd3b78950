//! End to end, issue 32 ("Reliability, round three"), items 4 and 6: a worker stopped
//! (SIGSTOP, as a Slurm suspend does) past its lease. Another worker takes the shard over; the
//! stopped one, continued, must not touch the new holder's shard and stops saying which lease
//! it lost (item 4). `run` whose own worker is stopped takes the shard back on a new worker and
//! says so, instead of waiting for ever (item 6). After each: every item exactly once and the
//! content digest of a clean run.
//!
//! The lease is made short with the hidden `--lease-ttl SECONDS` flag of `work` and `run`
//! (docs/RELIABILITY.md, "Leases and killed processes").

mod common;

use common::*;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Resolution of every job here: an item takes about half a second, so a shard of 12 items
/// outlasts the steps of a test.
const RESOLUTION: &str = "256";
/// The short lease of the workers stopped here, in seconds.
const LEASE_TTL: &str = "3";
/// The lease of a worker that must not lose it while the test runs, in seconds.
const LONG_LEASE_TTL: &str = "60";

/// A manifest of 12 meshes (the bundled examples, generated shapes, one broken file) and the
/// content digest of a clean run over it (one shard); built once for all tests.
struct Fixture {
    _dir: tempfile::TempDir,
    manifest: PathBuf,
    digest: String,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        let manifest = twelve_mesh_manifest(dir.path());
        let reference = dir.path().join("reference");
        init(&reference, &manifest);
        ok(&["run", s(&reference), "--workers", "1"]);
        assert_each_item_once(&reference);
        let digest = digest_of(&reference);
        Fixture {
            _dir: dir,
            manifest,
            digest,
        }
    })
}

fn init(job: &Path, manifest: &Path) {
    ok(&[
        "init",
        s(job),
        "--manifest",
        s(manifest),
        "--resolution",
        RESOLUTION,
        "--shard-size",
        "12",
    ]);
}

fn digest_of(job: &Path) -> String {
    inspect(job)["content_digest"]
        .as_str()
        .unwrap_or_default()
        .to_string()
}

/// Every item once, the clean run's digest, nothing pending.
fn assert_same_as_clean_run(job: &Path) {
    assert_each_item_once(job);
    assert_eq!(status(job)["pending"], 0);
    assert_eq!(
        digest_of(job),
        fixture().digest,
        "content differs from a clean run"
    );
}

fn signal(pid: u32, sig: i32) {
    // SAFETY: sending a signal to a process this test started (or its child).
    let rc = unsafe { libc::kill(pid as libc::pid_t, sig) };
    assert_eq!(rc, 0, "signal {sig} to {pid}");
}

/// A `sparc3d work --events` process on shard 0 with a lease of `ttl` seconds, its events
/// read as they come.
struct EventedWorker {
    child: Child,
    events: Receiver<serde_json::Value>,
    seen: Vec<serde_json::Value>,
}

impl EventedWorker {
    fn start(job: &Path, ttl: &str) -> Self {
        let mut child = Command::new(bin())
            .args(["work", s(job), "--shard-index", "0", "--events"])
            .args(["--lease-ttl", ttl])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("{e}"));
        let out = child.stdout.take().unwrap_or_else(|| panic!("no stdout"));
        let (tx, events) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                if let Ok(v) = serde_json::from_str(&line) {
                    if tx.send(v).is_err() {
                        return;
                    }
                }
            }
        });
        Self {
            child,
            events,
            seen: Vec::new(),
        }
    }

    /// Waits until `n` items finished and another one started.
    fn wait_mid_item_after(&mut self, n: usize) {
        let deadline = Instant::now() + Duration::from_secs(120);
        loop {
            let finished = self
                .seen
                .iter()
                .filter(|e| e["event"] == "item_finished")
                .count();
            let last_is_start = self
                .seen
                .last()
                .is_some_and(|e| e["event"] == "item_started");
            if finished >= n && last_is_start {
                return;
            }
            assert!(
                Instant::now() < deadline,
                "the worker did not get there: {:?}",
                self.seen
            );
            assert!(
                matches!(self.child.try_wait(), Ok(None)),
                "the worker ended too soon: {:?}",
                self.seen
            );
            if let Ok(e) = self.events.recv_timeout(Duration::from_millis(20)) {
                self.seen.push(e);
            }
        }
    }

    /// Waits for it to end (at most two minutes); its exit code and stderr.
    fn finish(mut self) -> (Option<i32>, String) {
        let deadline = Instant::now() + Duration::from_secs(120);
        while matches!(self.child.try_wait(), Ok(None)) {
            if Instant::now() > deadline {
                let _ = self.child.kill();
                let _ = self.child.wait();
                panic!("a worker still running after two minutes");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let out = self
            .child
            .wait_with_output()
            .unwrap_or_else(|e| panic!("{e}"));
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    }
}

/// The lease file of shard 0, parsed (`None` while absent or being replaced).
fn lease(job: &Path) -> Option<serde_json::Value> {
    let text = std::fs::read_to_string(job.join("state/part-00000.lease")).ok()?;
    serde_json::from_str(&text).ok()
}

fn now() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

/// Item 4: worker A is stopped mid-item past its lease; B takes shard 0 over and converts
/// items; A is continued while B still works. A must stop with a message naming the lease it
/// lost and write nothing B reads; B finishes the shard; the job equals a clean run.
#[test]
fn a_worker_stopped_past_its_lease_cannot_touch_the_new_holders_shard() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let job = tmp.path().join("job");
    init(&job, &fixture().manifest);
    let mut a = EventedWorker::start(&job, LEASE_TTL);
    a.wait_mid_item_after(1);
    let a_pid = a.child.id();
    signal(a_pid, libc::SIGSTOP);
    // Past A's lease: B takes it over as expired.
    let deadline = Instant::now() + Duration::from_secs(60);
    while lease(&job).is_some_and(|l| l["expires_at"].as_f64().unwrap_or(0.0) + 0.5 > now()) {
        assert!(Instant::now() < deadline, "A's lease never expired");
        std::thread::sleep(Duration::from_millis(50));
    }
    let mut b = EventedWorker::start(&job, LONG_LEASE_TTL);
    b.wait_mid_item_after(1);
    let b_owner = lease(&job)
        .and_then(|l| l["owner"].as_str().map(str::to_string))
        .unwrap_or_default();
    assert!(
        !b_owner.contains(&format!(":{a_pid}:")),
        "B does not hold the lease: {b_owner}"
    );
    signal(a_pid, libc::SIGCONT);
    let (a_code, a_err) = a.finish();
    let (b_code, b_err) = b.finish();
    assert_eq!(b_code, Some(0), "the new holder failed: {b_err}");
    assert!(
        a_err.contains("lost its lease") && a_err.contains("state/part-00000.lease"),
        "A's message does not name the lease it lost: {a_err}"
    );
    assert!(a_err.contains(&b_owner), "A does not name B: {a_err}");
    assert_eq!(a_code, Some(0), "{a_err}");
    assert!(
        job.join("shards/part-00000.complete.json").exists(),
        "B did not finish the shard: {b_err}"
    );
    assert_same_as_clean_run(&job);
}

/// Pids of the `sparc3d work` processes below `pid`.
fn work_processes(pid: u32) -> Vec<u32> {
    descendants(pid)
        .into_iter()
        .filter(|p| {
            std::fs::read(format!("/proc/{p}/cmdline"))
                .is_ok_and(|c| c.split(|&b| b == 0).nth(1) == Some(b"work".as_slice()))
        })
        .collect()
}

/// Whether a process exists and is not a zombie.
fn running(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|s| s.rsplit_once(')').map(|(_, r)| r.trim_start().to_string()))
        .is_some_and(|r| !r.starts_with('Z') && !r.starts_with('X'))
}

/// Item 6: `run`'s own worker is stopped mid-shard. `run` sees it make no progress past its
/// lease, kills it, starts the shard again on a new worker (which takes the expired lease
/// over), says so, and finishes the job like a clean run.
#[test]
fn run_takes_back_the_shard_of_its_stopped_worker() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let job = tmp.path().join("job");
    init(&job, &fixture().manifest);
    let mut run = Command::new(bin())
        .args(["run", s(&job), "--workers", "1", "--log-interval", "1s"])
        .args(["--lease-ttl", LEASE_TTL])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("{e}"));
    // Once its worker converts an item (the worker has its item worker), stop the worker.
    let deadline = Instant::now() + Duration::from_secs(120);
    let worker = loop {
        assert!(
            Instant::now() < deadline,
            "the worker never started an item"
        );
        assert!(matches!(run.try_wait(), Ok(None)), "run ended too soon");
        if let Some(&w) = work_processes(run.id()).first() {
            if !descendants(w).is_empty() {
                break w;
            }
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    signal(worker, libc::SIGSTOP);
    let deadline = Instant::now() + Duration::from_secs(120);
    while matches!(run.try_wait(), Ok(None)) {
        if Instant::now() > deadline {
            signal(worker, libc::SIGKILL);
            let _ = run.kill();
            let out = run.wait_with_output().unwrap_or_else(|e| panic!("{e}"));
            panic!(
                "run still waiting two minutes after its worker was stopped:\n{}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let out = run.wait_with_output().unwrap_or_else(|e| panic!("{e}"));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let said = format!("shard 0: worker {worker} made no progress past its lease");
    let line = err
        .lines()
        .find(|l| l.starts_with(&said))
        .unwrap_or_else(|| panic!("run did not say it took shard 0 back:\n{err}"));
    assert!(line.contains("new worker"), "{line}");
    assert!(!running(worker), "the stopped worker is still there");
    assert_same_as_clean_run(&job);
}
