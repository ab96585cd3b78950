//! End to end: config drift, bad files as failed rows, write failures, time-outs and retry,
//! `show` against `convert`, and `work` idempotence.

mod common;

use common::*;
use std::path::{Path, PathBuf};
use std::process::Command;

fn setup(tmp: &Path, name: &str, extra: &[&str]) -> (PathBuf, PathBuf) {
    setup_at(tmp, name, "48", extra)
}

/// A job over the test corpus at `resolution` (the manifest is built once per folder).
fn setup_at(tmp: &Path, name: &str, resolution: &str, extra: &[&str]) -> (PathBuf, PathBuf) {
    let meshes = corpus(tmp);
    let manifest = tmp.join("m.csv");
    if !manifest.exists() {
        ok(&[
            "manifest",
            "build",
            &meshes.to_string_lossy(),
            "-o",
            &manifest.to_string_lossy(),
        ]);
    }
    let job = tmp.join(name);
    let (j, m) = (job.to_string_lossy(), manifest.to_string_lossy());
    let mut args = init_args(&j, &m, resolution, "8").to_vec();
    args.extend_from_slice(extra);
    ok(&args);
    (job, manifest)
}

/// `init JOB --manifest MANIFEST --resolution R --shard-size S`, as arguments.
fn init_args<'a>(
    job: &'a str,
    manifest: &'a str,
    resolution: &'a str,
    shard_size: &'a str,
) -> [&'a str; 8] {
    [
        "init",
        job,
        "--manifest",
        manifest,
        "--resolution",
        resolution,
        "--shard-size",
        shard_size,
    ]
}

/// The job's `job.json`.
fn job_json(job: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(job.join("job.json")).unwrap_or_else(|e| panic!("{e}"));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn config_drift_is_refused_naming_the_keys() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let (job, manifest) = setup(tmp.path(), "job", &[]);
    let (j, m) = (job.to_string_lossy(), manifest.to_string_lossy());
    // Same config: accepted, nothing to do.
    ok(&init_args(&j, &m, "48", "8"));
    let out = sparc3d(&init_args(&j, &m, "64", "5"));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("params.resolution") && err.contains("shard_size"),
        "{err}"
    );
}

/// A job whose stored config has no `inside_test` key — what every binary wrote before the
/// inside test became the default, and what `inside_test = false` writes now — keeps the
/// test off: its job.json still has no key and the same fingerprint after a run, and
/// re-initialising it with the new default (the test on) is refused as a
/// changed config naming `params.inside_test`, so the default never leaks into an old job.
#[test]
fn a_job_stored_without_the_inside_test_key_resumes_with_it_off() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let toml = tmp.path().join("job.toml");
    std::fs::write(&toml, "[params]\ninside_test = false\n").unwrap_or_else(|e| panic!("{e}"));
    let (job, manifest) = setup(tmp.path(), "job", &["--config", &toml.to_string_lossy()]);
    let before = job_json(&job);
    assert!(
        before["config"]["params"].get("inside_test").is_none(),
        "{before}"
    );
    let j = job.to_string_lossy();
    ok(&["run", &j, "--workers", "2"]);
    let after = job_json(&job);
    assert!(
        after["config"]["params"].get("inside_test").is_none(),
        "{after}"
    );
    assert_eq!(after["fingerprint"], before["fingerprint"]);
    // A new job over the same manifest, with the default, has the test on and its own
    // fingerprint.
    let (new_job, _) = setup(tmp.path(), "new", &[]);
    let new = job_json(&new_job);
    assert_eq!(new["config"]["params"]["inside_test"], true);
    assert_ne!(new["fingerprint"], before["fingerprint"]);
    let out = sparc3d(&init_args(&j, &manifest.to_string_lossy(), "48", "8"));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("params.inside_test"), "{err}");
    // The refusal says how to resume such a job.
    assert!(err.contains("inside_test = false"), "{err}");
}

/// The same for the sealing of openings (`Params::seal_openings`): a job stored without the
/// key (every binary before the rule, and `seal_openings = false` now) keeps it off across a
/// run with its fingerprint, and re-initialising it with the new default is refused naming
/// `params.seal_openings`, saying how to resume it.
#[test]
fn a_job_stored_without_the_sealing_key_resumes_with_it_off() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let toml = tmp.path().join("job.toml");
    std::fs::write(&toml, "[params]\nseal_openings = false\n").unwrap_or_else(|e| panic!("{e}"));
    let (job, manifest) = setup(tmp.path(), "job", &["--config", &toml.to_string_lossy()]);
    let before = job_json(&job);
    let params = &before["config"]["params"];
    assert!(params.get("seal_openings").is_none(), "{before}");
    assert_eq!(params["inside_test"], true, "{before}");
    let j = job.to_string_lossy();
    ok(&["run", &j, "--workers", "2"]);
    let after = job_json(&job);
    assert!(
        after["config"]["params"].get("seal_openings").is_none(),
        "{after}"
    );
    assert_eq!(after["fingerprint"], before["fingerprint"]);
    let (new_job, _) = setup(tmp.path(), "new", &[]);
    assert_eq!(
        job_json(&new_job)["config"]["params"]["seal_openings"],
        true
    );
    let out = sparc3d(&init_args(&j, &manifest.to_string_lossy(), "48", "8"));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("params.seal_openings"), "{err}");
    assert!(err.contains("seal_openings = false"), "{err}");
}

#[test]
fn bad_files_become_failed_rows_and_show_matches_convert() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let (job, _) = setup(tmp.path(), "job", &[]);
    let j = job.to_string_lossy();
    ok(&["run", &j, "--workers", "2"]);
    assert_each_item_once(&job);
    let text = ok(&["failures", &j, "--json"]);
    let failed: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}")))
        .collect();
    for (name, class) in BROKEN {
        let f = failed
            .iter()
            .find(|f| f["uri"].as_str().is_some_and(|u| u.ends_with(name)))
            .unwrap_or_else(|| panic!("{name} did not fail: {text}"));
        if !class.is_empty() {
            assert_eq!(f["error_class"], class, "{name}");
        }
    }
    assert_eq!(
        failed.len(),
        BROKEN.len(),
        "only the broken files fail: {text}"
    );
    // show == convert for one item.
    let rows = all_rows(&job);
    let frozen = frozen_text(&job);
    let item: serde_json::Value = frozen
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find(|v| {
            v["uri"]
                .as_str()
                .is_some_and(|u| u.ends_with("sphere_03.obj"))
        })
        .unwrap_or_else(|| panic!("sphere_03 not in manifest"));
    assert!(rows
        .iter()
        .any(|r| r.1 == item["id"].as_str().unwrap_or("") && r.2 == "ok"));
    let shown = tmp.path().join("shown.ply");
    let converted = tmp.path().join("converted.ply");
    ok(&[
        "show",
        &j,
        "--id",
        item["id"].as_str().unwrap_or(""),
        "-o",
        &shown.to_string_lossy(),
    ]);
    ok(&[
        "convert",
        item["uri"].as_str().unwrap_or(""),
        "-o",
        &converted.to_string_lossy(),
        "--resolution",
        "48",
    ]);
    assert_eq!(
        std::fs::read(&shown).unwrap_or_default(),
        std::fs::read(&converted).unwrap_or_default(),
        "show and convert differ"
    );
    // work on a finished shard is a no-op.
    let before = std::fs::read(job.join("shards/part-00000.complete.json")).unwrap_or_default();
    ok(&["work", &j, "--shard-index", "0"]);
    assert_eq!(
        before,
        std::fs::read(job.join("shards/part-00000.complete.json")).unwrap_or_default()
    );
}

#[test]
fn write_failure_is_reported_and_the_job_resumes() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let (job, _) = setup(tmp.path(), "job", &[]);
    let j = job.to_string_lossy().into_owned();
    // 24 KiB per file: the journal or the shard outgrows it.
    let out = Command::new("bash")
        .args([
            "-c",
            "ulimit -f 24; exec \"$0\" work \"$1\" --shard-index 0",
            &bin().to_string_lossy(),
            &j,
        ])
        .output()
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(
        !out.status.success(),
        "work should fail under a file size limit"
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("file size limit") || err.contains("File too large"),
        "{err}"
    );
    assert!(!job.join("shards/part-00000.complete.json").exists());
    ok(&["run", &j, "--workers", "2"]);
    assert_each_item_once(&job);
    assert_eq!(status(&job)["pending"], 0);
}

#[test]
fn unwritable_output_folder_is_a_clear_error() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let (job, _) = setup(tmp.path(), "job", &[]);
    let j = job.to_string_lossy().into_owned();
    let state = job.join("state");
    std::fs::remove_dir_all(&state).unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(&state, "not a folder").unwrap_or_else(|e| panic!("{e}"));
    let out = sparc3d(&["work", &j, "--shard-index", "0"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("state"), "{err}");
    std::fs::remove_file(&state).unwrap_or_else(|e| panic!("{e}"));
    ok(&["run", &j, "--workers", "2"]);
    assert_each_item_once(&job);
}

#[test]
fn timeouts_are_failed_rows_and_retry_converts_them_again() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    // A resolution at which items take longer than the watchdog's 50 ms look, which keeps a
    // row that arrives before it.
    let (job, _) = setup_at(tmp.path(), "job", "320", &[]);
    let j = job.to_string_lossy().into_owned();
    let out = sparc3d(&["run", &j, "--workers", "2", "--item-timeout", "0.001"]);
    assert_each_item_once(&job);
    let s = status(&job);
    // When every item timed out, `run` says no item converted and exits 1 (issue 32, item 7).
    let none_ok = s["ok"] == 0 && out.status.code() == Some(1);
    assert!(
        out.status.success() || none_ok,
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Items that answer before the watchdog's first look are kept; the others time out.
    let timeouts = s["error_classes"]["timeout"].as_u64().unwrap_or(0);
    assert!(timeouts > 0, "{s}");
    ok(&["retry", &j, "--class", "timeout"]);
    assert_eq!(status(&job)["pending"].as_u64(), Some(timeouts));
    ok(&["run", &j, "--workers", "2"]);
    assert_each_item_once(&job);
    let s = status(&job);
    assert!(s["error_classes"].get("timeout").is_none(), "{s}");
    assert_eq!(s["failed"].as_u64(), Some(BROKEN.len() as u64), "{s}");
}
