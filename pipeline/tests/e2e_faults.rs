//! End to end, issue 10 ("Reliability, round two"): special files, and faults injected into a
//! real small job (a byte flipped inside a finished shard, a torn completion record, garbage
//! and empty leases, kill -9 of `run` started again at once, SIGTERM, a file-size limit, an
//! item memory limit too small). After each: every item exactly once, the content digest of
//! a clean run, and `run` exits 0 only when nothing is pending.

mod common;

use common::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Resolution of every job here: items take long enough for a kill to land mid-job.
const RESOLUTION: &str = "128";

/// A manifest of 12 meshes (the bundled examples, generated shapes, one broken file) and the
/// content digest of a clean run over it; built once for all tests.
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
        "3",
    ]);
}

/// A fresh job over the fixture's manifest, not run yet.
fn new_job(tmp: &Path) -> PathBuf {
    let job = tmp.join("job");
    init(&job, &fixture().manifest);
    job
}

/// A fresh job over the fixture's manifest, run to the end.
fn finished_job(tmp: &Path) -> PathBuf {
    let job = new_job(tmp);
    ok(&["run", s(&job), "--workers", "2"]);
    job
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

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs the binary, killing it and failing the test when it is still running after a minute
/// (a guard against the hangs this issue is about, not a speed target).
fn without_hanging(args: &[&str]) -> Output {
    let mut child = Command::new(bin())
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("{e}"));
    let deadline = Instant::now() + Duration::from_secs(60);
    while matches!(child.try_wait(), Ok(None)) {
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("sparc3d {args:?} still running after a minute");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap_or_else(|e| panic!("{e}"))
}

/// Item 1 and 11: FIFOs, links to /dev/zero and /dev/urandom and a name that is not UTF-8 are
/// skipped by the scan (named, counted); `convert` and `init` refuse them at once.
#[test]
fn special_files_and_odd_names_are_skipped_or_refused_at_once() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let dir = tmp.path().join("meshes");
    std::fs::create_dir(&dir).unwrap_or_else(|e| panic!("{e}"));
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    std::fs::copy(examples.join("cube.off"), dir.join("cube.off"))
        .unwrap_or_else(|e| panic!("{e}"));
    let fifo = dir.join("x.obj");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success()));
    std::os::unix::fs::symlink("/dev/zero", dir.join("zero.stl")).unwrap_or_else(|e| panic!("{e}"));
    std::os::unix::fs::symlink("/dev/urandom", dir.join("random.ply"))
        .unwrap_or_else(|e| panic!("{e}"));
    use std::os::unix::ffi::OsStrExt;
    let odd = dir.join(std::ffi::OsStr::from_bytes(b"caf\xe9.obj"));
    std::fs::copy(examples.join("sphere.obj"), &odd).unwrap_or_else(|e| panic!("{e}"));

    let manifest = tmp.path().join("m.jsonl");
    let out = without_hanging(&["manifest", "build", s(&dir), "-o", s(&manifest)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    for name in ["x.obj", "zero.stl", "random.ply", "caf\\xE9.obj"] {
        assert!(err.contains(name), "{name} not named: {err}");
    }
    assert!(err.contains("4 skipped"), "{err}");
    let text = std::fs::read_to_string(&manifest).unwrap_or_default();
    assert_eq!(text.lines().count(), 1, "only cube.off: {text}");

    for special in ["x.obj", "zero.stl", "random.ply"] {
        let p = dir.join(special);
        let out = without_hanging(&["convert", s(&p), "-o", s(&tmp.path().join("o.ply"))]);
        assert!(!out.status.success());
        assert!(
            stderr(&out).contains("not a regular file"),
            "{special}: {}",
            stderr(&out)
        );
        // A manifest with only a path: init hashes it for its id, and refuses it at once.
        let listed = tmp.path().join("paths.csv");
        std::fs::write(&listed, format!("path\n{}\n", p.display()))
            .unwrap_or_else(|e| panic!("{e}"));
        let job = tmp.path().join(format!("job-{special}"));
        let out = without_hanging(&["init", s(&job), "--manifest", s(&listed)]);
        assert!(!out.status.success());
        let err = stderr(&out);
        assert!(
            err.contains(special) && err.contains("not a regular file"),
            "{err}"
        );
    }
}

/// Flips one byte in the middle of a finished shard and sets its modification time back.
fn flip_byte(file: &Path) {
    let before = std::fs::metadata(file)
        .and_then(|m| m.modified())
        .unwrap_or_else(|e| panic!("{e}"));
    let mut bytes = std::fs::read(file).unwrap_or_else(|e| panic!("{e}"));
    let at = bytes.len() / 2;
    bytes[at] ^= 0x10;
    std::fs::write(file, &bytes).unwrap_or_else(|e| panic!("{e}"));
    std::fs::File::options()
        .write(true)
        .open(file)
        .and_then(|f| f.set_modified(before))
        .unwrap_or_else(|e| panic!("{e}"));
}

/// The id of an item of `shard`.
fn item_of_shard(job: &Path, shard: u64) -> String {
    let text = frozen_text(job);
    text.lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find(|v| v["shard"] == shard)
        .and_then(|v| v["id"].as_str().map(str::to_string))
        .unwrap_or_else(|| panic!("no item in shard {shard}"))
}

/// Items 2 and 6: a byte flipped inside a finished shard (same size, modification time put
/// back) is noticed by `status`, `inspect`, `show` and `verify`, and redone by `run`.
#[test]
fn flipped_byte_in_a_finished_shard_is_found_and_redone() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let job = finished_job(tmp.path());
    let j = s(&job);
    let shard_file = job.join("shards/part-00001.parquet");
    flip_byte(&shard_file);

    let st = status(&job);
    assert_eq!(st["shards_damaged"], 1, "{st}");
    assert!(st["pending"].as_u64() > Some(0), "{st}");
    let out = sparc3d(&["inspect", j]);
    assert!(!out.status.success(), "inspect trusted a damaged shard");
    assert!(stderr(&out).contains("shard 1"), "{}", stderr(&out));
    let out = sparc3d(&["inspect", s(&shard_file)]);
    assert!(!out.status.success(), "inspect of the file trusted it");
    let id = item_of_shard(&job, 1);
    let out = sparc3d(&["show", j, "--id", &id, "-o", s(&tmp.path().join("x.ply"))]);
    assert!(!out.status.success(), "show trusted a damaged shard");
    assert!(stderr(&out).contains("damaged"), "{}", stderr(&out));
    let out = sparc3d(&["verify", j, "--dry-run"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stdout).contains("shard 1: damaged"));
    assert!(shard_file.exists(), "--dry-run moved it");

    ok(&["run", j, "--workers", "2"]);
    assert_same_as_clean_run(&job);
    // The damaged file was moved aside, not deleted.
    let aside: Vec<PathBuf> = std::fs::read_dir(job.join("quarantine"))
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    assert_eq!(aside.len(), 1, "{aside:?}");
    assert!(aside[0].join("part-00001.parquet").exists());
    assert!(aside[0].join("reason.txt").exists());

    // `verify` moves a damaged shard aside itself; `run` redoes it.
    flip_byte(&job.join("shards/part-00002.parquet"));
    let out = sparc3d(&["verify", j]);
    assert_eq!(out.status.code(), Some(1));
    assert!(!job.join("shards/part-00002.complete.json").exists());
    ok(&["run", j, "--workers", "2"]);
    assert_same_as_clean_run(&job);
    ok(&["verify", j]);
}

/// Items 4 and 6: a torn completion record, or a truncated shard, is damage that `run`
/// repairs by itself; `inspect` names the shard and fails meanwhile.
#[test]
fn torn_record_and_truncated_shard_do_not_block_the_job() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let job = finished_job(tmp.path());
    let j = s(&job);
    let record = job.join("shards/part-00000.complete.json");
    let text = std::fs::read(&record).unwrap_or_default();
    std::fs::write(&record, &text[..text.len() / 2]).unwrap_or_else(|e| panic!("{e}"));
    let shard = job.join("shards/part-00003.parquet");
    let bytes = std::fs::read(&shard).unwrap_or_default();
    std::fs::write(&shard, &bytes[..bytes.len() - 100]).unwrap_or_else(|e| panic!("{e}"));

    let st = status(&job);
    assert_eq!(st["shards_damaged"], 2, "{st}");
    let out = sparc3d(&["inspect", j]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(err.contains("shard 0") && err.contains("shard 3"), "{err}");
    ok(&["run", j, "--workers", "2"]);
    assert_same_as_clean_run(&job);
}

/// Item 5: leases holding garbage or zero bytes are stale by definition; the run goes on.
#[test]
fn garbage_and_empty_leases_do_not_stall_the_run() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let job = new_job(tmp.path());
    let state = job.join("state");
    std::fs::write(state.join("part-00000.lease"), b"\x00garbage{")
        .unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(state.join("part-00002.lease"), b"").unwrap_or_else(|e| panic!("{e}"));
    ok(&["run", s(&job), "--workers", "2"]);
    assert_same_as_clean_run(&job);
    let leases: Vec<_> = std::fs::read_dir(&state)
        .map(|d| d.flatten().map(|e| e.file_name()).collect())
        .unwrap_or_default();
    assert!(leases.is_empty(), "left behind: {leases:?}");
}

/// Whether a process exists and is not a zombie.
fn running(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|s| s.rsplit_once(')').map(|(_, r)| r.trim_start().to_string()))
        .is_some_and(|r| !r.starts_with('Z') && !r.starts_with('X'))
}

/// Item 3: `run` killed with -9 mid-job and started again at once: its workers die with it,
/// the new run takes their shards over when their leases go, and exits 0 with nothing
/// pending and the clean run's content.
#[test]
fn kill_9_of_run_and_an_immediate_restart_finish_the_job() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let job = new_job(tmp.path());
    let j = s(&job);
    let mut first = Command::new(bin())
        .args(["run", j, "--workers", "2"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap_or_else(|e| panic!("{e}"));
    // Wait until both workers run an item (each `work` has its item worker).
    let deadline = Instant::now() + Duration::from_secs(120);
    let children = loop {
        assert!(Instant::now() < deadline, "the workers never started");
        assert!(
            matches!(first.try_wait(), Ok(None)),
            "the job finished before the kill"
        );
        let d = descendants(first.id());
        if d.len() >= 4 {
            break d;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    assert!(kill9(first.id()));
    let _ = first.wait();
    let second = sparc3d(&["run", j, "--workers", "2"]);
    let pending = status(&job)["pending"].as_u64();
    assert!(
        second.status.success(),
        "the second run failed: {}",
        stderr(&second)
    );
    assert_eq!(pending, Some(0), "run exited 0 with items pending");
    assert_same_as_clean_run(&job);
    // No worker of the killed run is left running.
    let deadline = Instant::now() + Duration::from_secs(30);
    while children.iter().any(|&p| running(p)) && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(50));
    }
    let alive: Vec<u32> = children.into_iter().filter(|&p| running(p)).collect();
    assert!(
        alive.is_empty(),
        "workers of the killed run still running: {alive:?}"
    );
}

/// Item 12: SIGTERM stops `run` (and `work`) cleanly with status 143, and a later run
/// finishes the job.
#[test]
fn sigterm_exits_143_and_the_job_resumes() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let job = new_job(tmp.path());
    let j = s(&job);
    for cmd in [
        vec!["run", j, "--workers", "1"],
        vec!["work", j, "--shard-index", "1"],
    ] {
        let mut child = Command::new(bin())
            .args(&cmd)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("{e}"));
        // Once an item worker runs, the command is mid-shard.
        let want = if cmd[0] == "run" { 2 } else { 1 };
        let deadline = Instant::now() + Duration::from_secs(120);
        while descendants(child.id()).len() < want {
            assert!(Instant::now() < deadline, "{cmd:?} never started an item");
            assert!(
                matches!(child.try_wait(), Ok(None)),
                "{cmd:?} ended too soon"
            );
            std::thread::sleep(Duration::from_millis(5));
        }
        // SAFETY: sending SIGTERM to a child we started.
        unsafe {
            libc::kill(child.id() as libc::pid_t, libc::SIGTERM);
        }
        let code = child
            .wait()
            .map(|s| s.code())
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(code, Some(143), "{cmd:?}");
    }
    ok(&["run", j, "--workers", "2"]);
    assert_same_as_clean_run(&job);
}

/// Item 12: a run that cannot write (a file-size limit standing in for a full disk) says why
/// each shard failed, goes on with the others, exits non-zero naming what is left, and the
/// next run finishes the job.
#[test]
fn write_failures_are_explained_and_the_run_exits_non_zero() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let job = new_job(tmp.path());
    let j = s(&job);
    let out = Command::new("bash")
        .args([
            "-c",
            "ulimit -f 16; exec \"$0\" run \"$1\" --workers 2",
            s(&bin()),
            j,
        ])
        .output()
        .unwrap_or_else(|e| panic!("{e}"));
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    let failed: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("shard ") && l.contains(" failed ("))
        .collect();
    assert!(!failed.is_empty(), "{err}");
    for line in &failed {
        let reason = line.split_once("): ").map(|x| x.1).unwrap_or("");
        assert!(reason.contains("file size limit"), "no reason: {line}");
    }
    assert!(err.contains("not finished"), "{err}");
    ok(&["run", j, "--workers", "2"]);
    assert_same_as_clean_run(&job);
}

/// Item 12: an item memory limit too small to start the conversion thread says so, naming
/// the limit, without repeating the class in the message. Every item fails for it, so `run`
/// exits 1 (issue 32, item 7: a cause that affects every item is no success).
#[test]
fn too_small_item_memory_names_the_limit() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let job = new_job(tmp.path());
    let out = sparc3d(&["run", s(&job), "--workers", "2", "--item-memory", "20M"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("no item converted"),
        "{}",
        stderr(&out)
    );
    assert_eq!(status(&job)["pending"], 0);
    let text = ok(&["failures", s(&job), "--json"]);
    let mut n = 0;
    for line in text.lines() {
        let f: serde_json::Value = serde_json::from_str(line).unwrap_or_else(|e| panic!("{e}"));
        if f["error_class"] != "out_of_memory" {
            continue;
        }
        n += 1;
        let msg = f["error_message"].as_str().unwrap_or_default();
        assert!(
            msg.contains("limit of 20M") && msg.contains("too small"),
            "{msg}"
        );
        assert!(!msg.starts_with("out of memory"), "{msg}");
    }
    assert!(n > 0, "no item hit the limit: {text}");
}

/// A finished shard whose bytes no longer hash to its record's sha256 while its size and
/// stamp still match (bit rot under an unchanged stamp; made here by changing the recorded
/// sha256): `export` hashes every shard it reads, on a thread beside the read, so it fails
/// naming the shard and writes nothing; the items of sound shards still export.
#[test]
fn export_hashes_each_shard_it_reads_even_under_an_unchanged_stamp() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let job = finished_job(tmp.path());
    let j = s(&job);
    let record = job.join("shards/part-00001.complete.json");
    let text = std::fs::read_to_string(&record).unwrap_or_else(|e| panic!("{e}"));
    let mut value: serde_json::Value =
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}"));
    value["sha256"] = serde_json::Value::String("0".repeat(64));
    std::fs::write(&record, value.to_string()).unwrap_or_else(|e| panic!("{e}"));
    // The quick check (size and stamp) of `status` still trusts it.
    assert_eq!(status(&job)["shards_damaged"], 0);

    // TRELLIS.2 in the job's own frame (its own needs a job made with --for trellis2@G).
    for (format, frame) in [("trellis2", "normalized"), ("cubvh", "consumer")] {
        let out_dir = tmp.path().join(format!("export-{format}"));
        let out = sparc3d(&[
            "export",
            j,
            "--format",
            format,
            "--frame",
            frame,
            "--out",
            s(&out_dir),
        ]);
        let err = stderr(&out);
        assert!(!out.status.success(), "{format}: exported a damaged shard");
        assert!(err.contains("shard 1") && err.contains("sha256"), "{err}");
        assert!(!out_dir.exists(), "{format}: wrote {}", out_dir.display());
    }
    let sound = item_of_shard(&job, 0);
    let out_dir = tmp.path().join("export-sound");
    ok(&[
        "export",
        j,
        "--format",
        "trellis2",
        "--frame",
        "normalized",
        "--ids",
        &sound,
        "--out",
        s(&out_dir),
    ]);
    assert!(out_dir.join("mesh_dumps").is_dir());
}

/// The pid of a process that has exited (and been reaped).
fn dead_pid() -> u32 {
    let mut child = std::process::Command::new("true")
        .spawn()
        .unwrap_or_else(|e| panic!("{e}"));
    let pid = child.id();
    child.wait().unwrap_or_else(|e| panic!("{e}"));
    pid
}

/// Issue 64 item 7: the `.DIR.partial-PID` and `.DIR.old-PID` folders that exports killed with
/// `kill -9` left are cleared by the next export of DIR; one killed between its two renames
/// (DIR moved aside, nothing in its place) gets the earlier export back, even when the next
/// export then fails; an export over an earlier one leaves nothing beside it.
#[test]
fn exports_clear_what_killed_exports_left_and_restore_one_moved_aside() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let job = finished_job(tmp.path());
    let out = tmp.path().join("export");
    let export = |extra: &[&str]| {
        let mut args = vec!["export", s(&job), "--format", "cubvh", "--out", s(&out)];
        args.extend_from_slice(extra);
        sparc3d(&args)
    };
    let beside = || -> Vec<String> {
        let entries = std::fs::read_dir(tmp.path()).unwrap_or_else(|e| panic!("{e}"));
        let mut names: Vec<String> = entries
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(".export."))
            .collect();
        names.sort();
        names
    };
    assert!(export(&[]).status.success());
    let record = out.join(".sparc3d-export.json");
    assert!(record.is_file());
    // Debris of two killed exports.
    let pid = dead_pid();
    for kind in ["partial", "old"] {
        let dir = tmp.path().join(format!(".export.{kind}-{pid}"));
        std::fs::create_dir_all(dir.join("items")).unwrap_or_else(|e| panic!("{e}"));
        std::fs::write(dir.join("items/half"), b"x").unwrap_or_else(|e| panic!("{e}"));
    }
    let again = export(&[]);
    assert!(again.status.success(), "{}", stderr(&again));
    assert_eq!(beside(), Vec::<String>::new(), "{}", stderr(&again));
    assert!(record.is_file());
    // Killed between the renames: the export moved aside, nothing at DIR.
    let aside = tmp.path().join(format!(".export.old-{pid}"));
    std::fs::rename(&out, &aside).unwrap_or_else(|e| panic!("{e}"));
    let failed = export(&["--ids", "no-such-item"]);
    assert!(!failed.status.success());
    assert!(record.is_file(), "{}", stderr(&failed));
    assert_eq!(beside(), Vec::<String>::new());
}

/// Makes `file` impossible to unlink until dropped: immutable (`chattr +i`) as root, whom
/// permissions do not stop; its folder read-only otherwise.
struct Unremovable(PathBuf);

impl Unremovable {
    fn new(file: &Path) -> Self {
        let done = if is_root() {
            Command::new("chattr").arg("+i").arg(file).status()
        } else {
            Command::new("chmod")
                .arg("555")
                .arg(parent_of(file))
                .status()
        };
        let done = done.unwrap_or_else(|e| panic!("locking {}: {e}", file.display()));
        assert!(done.success(), "could not lock {}", file.display());
        Unremovable(file.to_path_buf())
    }
}

impl Drop for Unremovable {
    fn drop(&mut self) {
        let _ = Command::new("chattr").arg("-i").arg(&self.0).status();
        let _ = Command::new("chmod")
            .arg("755")
            .arg(parent_of(&self.0))
            .status();
    }
}

fn parent_of(file: &Path) -> &Path {
    file.parent()
        .unwrap_or_else(|| panic!("{} has no folder", file.display()))
}

/// Whether the tests run as root (`id -u` is 0).
fn is_root() -> bool {
    let out = Command::new("id").arg("-u").output();
    let out = out.unwrap_or_else(|e| panic!("id -u: {e}"));
    String::from_utf8_lossy(&out.stdout).trim() == "0"
}

/// Issue 64 item 7: an export over an earlier one that cannot be removed (read-only) is
/// complete and in place, exits 0 and says what it left where (before: exit 1 after the new
/// export was in place); the next export, once it can, removes what was left.
#[test]
fn an_export_over_an_earlier_one_that_cannot_be_removed_succeeds_and_says_so() {
    // On the checkout's file system (ext4 here and in CI), where `chattr` works.
    let tmp = tempfile::tempdir_in(env!("CARGO_TARGET_TMPDIR")).unwrap_or_else(|e| panic!("{e}"));
    let job = finished_job(tmp.path());
    let out = tmp.path().join("export");
    let export = || sparc3d(&["export", s(&job), "--format", "cubvh", "--out", s(&out)]);
    assert!(export().status.success());
    let record = out.join(".sparc3d-export.json");
    let before = std::fs::read(&record).unwrap_or_else(|e| panic!("{e}"));
    let lock = Unremovable::new(&record);
    let again = export();
    let said = stderr(&again);
    assert!(again.status.success(), "{said}");
    assert!(
        said.contains("could not be removed") && said.contains("by hand"),
        "{said}"
    );
    assert!(record.is_file(), "{said}");
    let left: Vec<PathBuf> = std::fs::read_dir(tmp.path())
        .unwrap_or_else(|e| panic!("{e}"))
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.to_string_lossy().contains("/.export."))
        .collect();
    assert_eq!(left.len(), 1, "{left:?}");
    let kept =
        std::fs::read(left[0].join(".sparc3d-export.json")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(kept, before, "the earlier export is what was left");
    // Still locked, the leftover is said and left; unlocked, the next export removes it.
    let locked = export();
    assert!(locked.status.success(), "{}", stderr(&locked));
    assert!(left[0].exists());
    drop(lock);
    let _ = Command::new("chattr")
        .arg("-i")
        .arg(left[0].join(".sparc3d-export.json"))
        .status();
    let _ = Command::new("chmod").arg("755").arg(&left[0]).status();
    let cleared = export();
    assert!(cleared.status.success(), "{}", stderr(&cleared));
    assert!(!left[0].exists(), "{}", stderr(&cleared));
}
