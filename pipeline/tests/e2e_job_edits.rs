//! End to end, issue 32 ("Reliability, round three"), item 3 and the `verify` note of item 8:
//! hand edits of a job's own files are found when the job is opened. An edited resolution or
//! shard size, an out-of-range resolution and an edited path in the frozen manifest are refused
//! by every command that changes the job (naming the file and what differs), read-only commands
//! say what they found, and `init` with the original manifest names the edited line (with
//! another manifest, the first line where the frozen copy differs from it). Restored,
//! the job finishes as a clean one would. `verify` killed part-way never leaves a note for a
//! shard still in place.

mod common;

use common::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A manifest of the five bundled examples (ids are their sha256).
fn manifest(dir: &Path) -> PathBuf {
    let meshes = dir.join("meshes");
    std::fs::create_dir_all(&meshes).unwrap_or_else(|e| panic!("{e}"));
    for n in [
        "cube.off",
        "sphere.obj",
        "wuson.stl",
        "cube_binary.ply",
        "box_textured.glb",
    ] {
        std::fs::copy(example(n), meshes.join(n)).unwrap_or_else(|e| panic!("{e}"));
    }
    let m = dir.join("m.csv");
    ok(&["manifest", "build", s(&meshes), "-o", s(&m)]);
    m
}

fn init_args<'a>(job: &'a Path, m: &'a Path) -> [&'a str; 8] {
    [
        "init",
        s(job),
        "--manifest",
        s(m),
        "--resolution",
        "32",
        "--shard-size",
        "2",
    ]
}

/// A job of 5 items in shards of 2 with its first shard converted.
fn job_with_one_shard(dir: &Path) -> (PathBuf, PathBuf) {
    let m = manifest(dir);
    let job = dir.join("job");
    ok(&init_args(&job, &m));
    ok(&["work", s(&job), "--shard-index", "0"]);
    (job, m)
}

/// Replaces `from` with `to` in a job file, once; returns the original bytes.
fn edit(file: &Path, from: &str, to: &str) -> Vec<u8> {
    let before = std::fs::read(file).unwrap_or_else(|e| panic!("{e}"));
    let text = String::from_utf8_lossy(&before);
    assert!(text.contains(from), "{from:?} not in {}", file.display());
    std::fs::write(file, text.replacen(from, to, 1)).unwrap_or_else(|e| panic!("{e}"));
    before
}

/// Every command that changes a job refuses it, naming what `says` names; `status` and `ls`
/// still read it and warn with the same.
fn assert_refused(job: &Path, says: &[&str]) {
    assert_refused_at(job, says, "1", &["status", "ls"]);
}

/// [`assert_refused`] with `work` on shard `shard`, and only the read-only commands `warners`
/// expected to warn (`status` reads no slice of the frozen manifest, so an edited slice is not
/// its to see).
fn assert_refused_at(job: &Path, says: &[&str], shard: &str, warners: &[&str]) {
    let j = s(job);
    for args in [
        vec!["run", j, "--workers", "1"],
        vec!["work", j, "--shard-index", shard],
        vec!["retry", j],
        vec!["verify", j],
        vec!["verify", j, "--dry-run"],
    ] {
        let out = sparc3d(&args);
        let err = stderr(&out);
        assert!(!out.status.success(), "{args:?} accepted an edited job");
        assert!(
            err.contains("was changed after `sparc3d init`"),
            "{args:?}: {err}"
        );
        for what in says {
            assert!(err.contains(what), "{args:?} does not name {what:?}: {err}");
        }
        assert!(!err.contains("in 0 shards"), "{err}");
    }
    for command in warners {
        let args = vec![*command, j];
        let out = sparc3d(&args);
        let err = stderr(&out);
        assert!(out.status.success(), "{args:?}: {err}");
        for what in says {
            assert!(
                err.contains(what),
                "{args:?} does not warn of {what:?}: {err}"
            );
        }
    }
}

/// After the edit is undone, the job runs to the end: every item once, one resolution.
fn assert_finishes_when_restored(job: &Path, file: &Path, original: &[u8]) {
    std::fs::write(file, original).unwrap_or_else(|e| panic!("{e}"));
    ok(&["run", s(job), "--workers", "2"]);
    assert_each_item_once(job);
    assert_eq!(status(job)["ok"], 5);
    let digest = inspect(job)["content_digest"].clone();
    assert!(digest.is_string());
    ok(&["verify", s(job)]);
}

/// Item 3: the resolution edited in job.json after a shard ran is refused by `run`, `work`,
/// `retry` and `verify` (it would mix 32³ and 64³ rows), naming the key and both values.
#[test]
fn an_edited_resolution_is_refused_naming_the_key() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let (job, _) = job_with_one_shard(tmp.path());
    let file = job.join("job.json");
    let original = edit(&file, "\"resolution\": 32", "\"resolution\": 64");
    assert_refused(
        &job,
        &[
            "job.json",
            "params.resolution is 64, the shards were written with 32",
        ],
    );
    assert_finishes_when_restored(&job, &file, &original);
}

/// Item 3: `shard_size` edited after one shard ran (it would convert one item twice and two
/// never) is refused, naming the key; `run` never prints "in 0 shards".
#[test]
fn an_edited_shard_size_is_refused_naming_the_key() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let (job, _) = job_with_one_shard(tmp.path());
    let file = job.join("job.json");
    let original = edit(&file, "\"shard_size\": 2", "\"shard_size\": 3");
    assert_refused(
        &job,
        &[
            "job.json",
            "shard_size is 3, the shards were written with 2",
        ],
    );
    assert_finishes_when_restored(&job, &file, &original);
}

/// Item 3: a resolution of 0 or 5000 written into job.json is refused with the valid range
/// before any item fails for it.
#[test]
fn an_out_of_range_resolution_is_refused_with_the_valid_range() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let (job, _) = job_with_one_shard(tmp.path());
    let file = job.join("job.json");
    for bad in ["0", "5000"] {
        let original = edit(
            &file,
            "\"resolution\": 32",
            &format!("\"resolution\": {bad}"),
        );
        let range = format!(
            "resolution must be in 8..={}, got {bad}",
            sparcubes::params::MAX_RESOLUTION
        );
        assert_refused(&job, &["job.json", &range]);
        std::fs::write(&file, &original).unwrap_or_else(|e| panic!("{e}"));
    }
    assert_finishes_when_restored(&job, &file, &std::fs::read(&file).unwrap_or_default());
}

/// Item 3: a path edited in the frozen manifest (it would convert another file under the old
/// id) is refused, naming the slice it is in; `init` with the original manifest no longer says
/// "already initialised" but names the edited line.
#[test]
fn an_edited_path_in_the_frozen_manifest_is_refused_and_init_names_the_line() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let (job, m) = job_with_one_shard(tmp.path());
    let file = slice_files(&job)
        .into_iter()
        .find(|f| std::fs::read_to_string(f).is_ok_and(|t| t.contains("meshes/sphere.obj")))
        .unwrap_or_else(|| panic!("no slice holds sphere.obj"));
    let name = file
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let shard = name["part-".len().."part-00000".len()]
        .trim_start_matches('0')
        .to_string();
    let shard = if shard.is_empty() {
        "0".to_string()
    } else {
        shard
    };
    let original = edit(&file, "meshes/sphere.obj", "meshes/wuson.stl");
    let named = format!("manifest/{name}");
    assert_refused_at(
        &job,
        &[&named, "the frozen manifest was edited"],
        &shard,
        &["ls"],
    );
    let out = sparc3d(&init_args(&job, &m));
    let err = stderr(&out);
    assert!(!out.status.success(), "{err}");
    assert!(!err.contains("already initialised"), "{err}");
    assert!(
        err.contains("this manifest is the one") && err.contains("line "),
        "{err}"
    );
    assert!(
        err.contains("wuson.stl") && err.contains("sphere.obj"),
        "{err}"
    );
    // Issue 41, defect 7: with another manifest (its last row left out), `init` said two
    // hashes; it names the first line where the frozen copy differs from that manifest.
    let text = std::fs::read_to_string(&m).unwrap_or_default();
    let rows: Vec<&str> = text.lines().collect();
    let other = tmp.path().join("fewer.csv");
    std::fs::write(&other, rows[..rows.len() - 1].join("\n") + "\n")
        .unwrap_or_else(|e| panic!("{e}"));
    let out = sparc3d(&init_args(&job, &other));
    let err = stderr(&out);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("is not the one") && err.contains("first differs from this manifest at line"),
        "{err}"
    );
    assert!(
        err.contains("wuson.stl") && err.contains("sphere.obj"),
        "{err}"
    );
    assert_finishes_when_restored(&job, &file, &original);
    let out = sparc3d(&init_args(&job, &m));
    assert!(
        stderr(&out).contains("already initialised with this config and manifest"),
        "{}",
        stderr(&out)
    );
}

/// Flips one byte in the middle of a file.
fn flip_byte(file: &Path) {
    let mut bytes = std::fs::read(file).unwrap_or_else(|e| panic!("{e}"));
    let at = bytes.len() / 2;
    bytes[at] ^= 0x10;
    std::fs::write(file, &bytes).unwrap_or_else(|e| panic!("{e}"));
}

/// Folders of `quarantine/` holding a `reason.txt`.
fn noted(job: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(job.join("quarantine"))
        .map(|d| d.flatten().map(|e| e.path()).collect::<Vec<_>>())
        .unwrap_or_default()
        .into_iter()
        .filter(|d| d.join("reason.txt").exists())
        .collect()
}

/// Item 8: `verify` killed (SIGKILL) as soon as a quarantine note appears never leaves a note
/// beside which the shard's completion record is missing (a note that says "moved aside" for a
/// shard still in place); every file a note names is in its folder. Then `run` redoes the job.
#[test]
fn verify_killed_part_way_never_leaves_a_note_for_a_shard_in_place() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let m = manifest(tmp.path());
    let template = tmp.path().join("template");
    ok(&[
        "init",
        s(&template),
        "--manifest",
        s(&m),
        "--resolution",
        "16",
        "--shard-size",
        "1",
    ]);
    ok(&["run", s(&template), "--workers", "2"]);
    for trial in 0..6 {
        let job = tmp.path().join(format!("job{trial}"));
        let copied = Command::new("cp")
            .args(["-a", s(&template), s(&job)])
            .status()
            .is_ok_and(|st| st.success());
        assert!(copied);
        for shard in 0..5 {
            flip_byte(&job.join(format!("shards/part-{shard:05}.parquet")));
        }
        let mut child = Command::new(bin())
            .args(["verify", s(&job)])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("{e}"));
        while matches!(child.try_wait(), Ok(None)) && noted(&job).is_empty() {}
        let _ = child.kill();
        let _ = child.wait();
        for dir in noted(&job) {
            let note = std::fs::read_to_string(dir.join("reason.txt")).unwrap_or_default();
            let name = dir.file_name().map(|n| n.to_string_lossy().into_owned());
            let shard = name
                .as_deref()
                .and_then(|n| n.get(..10))
                .unwrap_or_default();
            assert!(
                dir.join(format!("{shard}.complete.json")).exists(),
                "trial {trial}: {} has a note but not the record it moved aside: {note}",
                dir.display()
            );
            for moved in note
                .lines()
                .nth(1)
                .and_then(|l| l.split(": ").nth(1))
                .into_iter()
            {
                for f in moved.split(", ") {
                    assert!(
                        dir.join(f).exists(),
                        "trial {trial}: {f} not in {}",
                        dir.display()
                    );
                }
            }
        }
        ok(&["run", s(&job), "--workers", "2"]);
        assert_each_item_once(&job);
        assert_eq!(status(&job)["ok"], 5);
    }
}
