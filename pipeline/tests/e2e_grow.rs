//! Jobs that grow (`sparc3d add`, `run DIR --job JOB` on a job): new items in new shards after
//! the existing ones, finished shards untouched, one job for `status`, `ls` and `inspect`, and
//! the job lock that keeps an add from changing a job under a run or another add.

mod common;
use common::*;
use sparc3d_schema::JobLayout;
use sparc3d_workers::job::lock::JobLock;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

const MESHES: [&str; 5] = [
    "cube.off",
    "sphere.obj",
    "wuson.stl",
    "box_textured.glb",
    "cube_binary.ply",
];
const CONFIG: [&str; 4] = ["--resolution", "32", "--shard-size", "2"];

/// The examples in `dir/meshes` and manifests of their first `n` rows for each `n` (with a
/// licence column), all naming the same files.
fn manifests(dir: &Path, parts: &[usize]) -> Vec<PathBuf> {
    let meshes = dir.join("meshes");
    std::fs::create_dir_all(&meshes).unwrap_or_else(|e| panic!("{e}"));
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    for name in MESHES {
        std::fs::copy(examples.join(name), meshes.join(name)).unwrap_or_else(|e| panic!("{e}"));
    }
    let licences = ["cc0", "cc-by", "cc0", "by-sa", "cc-by"];
    parts
        .iter()
        .map(|&n| {
            let rows: Vec<String> = MESHES[..n]
                .iter()
                .zip(licences)
                .map(|(m, l)| format!("meshes/{m},{l}"))
                .collect();
            let path = dir.join(format!("first{n}.csv"));
            std::fs::write(&path, format!("path,license\n{}\n", rows.join("\n")))
                .unwrap_or_else(|e| panic!("{e}"));
            path
        })
        .collect()
}

fn digests(job: &Path) -> (String, String) {
    let i = inspect(job);
    let get = |k: &str| i[k].as_str().unwrap_or_default().to_string();
    (get("content_digest"), get("items_digest"))
}

/// Runs `sparc3d add` and returns its stderr.
fn add(job: &Path, input: &Path) -> String {
    let out = sparc3d(&["add", s(job), s(input)]);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "add failed: {err}");
    err
}

/// Makes `job` from manifest `m` (or grows it, when it exists) with two workers and
/// [`CONFIG`].
fn run_job(m: &Path, job: &Path) -> String {
    ok(&[
        &["run", s(m), "--job", s(job), "--workers", "2"][..],
        &CONFIG,
    ]
    .concat())
}

#[test]
fn adding_twice_gives_the_job_made_at_once() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let m = manifests(tmp.path(), &[2, 4, 5]);
    let at_once = tmp.path().join("at-once");
    run_job(&m[2], &at_once);

    let grown = tmp.path().join("grown");
    run_job(&m[0], &grown);
    let job_json = std::fs::read_to_string(grown.join("job.json")).unwrap_or_default();
    let first = std::fs::read(grown.join("shards/part-00000.parquet")).unwrap_or_default();
    let err = add(&grown, &m[1]);
    assert!(
        err.contains("added 2 new items as shards 1..1 (2 rows are in the job already)"),
        "{err}"
    );
    // The status sees one job with the new items pending; nothing finished was touched.
    assert_eq!(status(&grown)["pending"], 2);
    ok(&["run", s(&grown), "--workers", "1"]);
    let err = add(&grown, &m[2]);
    assert!(err.contains("added 1 new items as shards 2..2"), "{err}");
    ok(&["run", s(&grown), "--workers", "2"]);

    assert_eq!(manifest_ids(&grown), manifest_ids(&at_once));
    assert_each_item_once(&grown);
    assert_eq!(digests(&grown), digests(&at_once));
    assert_eq!(
        std::fs::read(grown.join("shards/part-00000.parquet")).unwrap_or_default(),
        first
    );
    let now: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(grown.join("job.json")).unwrap_or_default())
            .unwrap_or_default();
    let then: serde_json::Value = serde_json::from_str(&job_json).unwrap_or_default();
    assert_eq!(now["fingerprint"], then["fingerprint"]);
    assert_eq!(now["config"], then["config"]);
    assert_eq!(
        (now["items"].as_u64(), now["shards"].as_u64()),
        (Some(5), Some(3))
    );
    let ls = ok(&["ls", s(&grown)]);
    assert_eq!(
        ls.lines().filter(|l| l.contains("\tok\t")).count(),
        5,
        "{ls}"
    );
    assert!(
        ls.lines()
            .nth(4)
            .is_some_and(|l| l.ends_with("license=cc-by")),
        "{ls}"
    );
    // An export sees one job: every item, the added ones included.
    let export = tmp.path().join("export");
    ok(&[
        "export",
        s(&grown),
        "--format",
        "cubvh",
        "--out",
        s(&export),
    ]);
    let record = std::fs::read_to_string(export.join(".sparc3d-export.json")).unwrap_or_default();
    let record: serde_json::Value = serde_json::from_str(&record).unwrap_or_default();
    let ids: Vec<&str> = record["items"]
        .as_array()
        .map(|a| a.iter().filter_map(|i| i["id"].as_str()).collect())
        .unwrap_or_default();
    assert_eq!(ids, manifest_ids(&at_once));
}

/// When an earlier part does not fill its last shard, the new items start a shard of their
/// own: the shard digests (and so the content digest) differ from the job made at once, the
/// rows in item order (the items digest) do not.
#[test]
fn a_partial_last_shard_is_never_refilled_and_the_items_digest_still_agrees() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let m = manifests(tmp.path(), &[3, 5]);
    let at_once = tmp.path().join("at-once");
    run_job(&m[1], &at_once);
    let grown = tmp.path().join("grown");
    run_job(&m[0], &grown);
    let partial = std::fs::read(grown.join("shards/part-00001.parquet")).unwrap_or_default();
    // `run MANIFEST --job JOB` on the job says what is new and adds it.
    let out = sparc3d(
        &[
            &["run", s(&m[1]), "--job", s(&grown), "--workers", "2"][..],
            &CONFIG,
        ]
        .concat(),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && err.contains("added 2 new items as shards 2..2"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(grown.join("shards/part-00001.parquet")).unwrap_or_default(),
        partial
    );
    let (grown_content, grown_items) = digests(&grown);
    let (content, items) = digests(&at_once);
    assert_ne!(
        grown_content, content,
        "shards [0,1] [2] [3,4] against [0,1] [2,3] [4]"
    );
    assert_eq!(grown_items, items);
    assert_eq!(status(&grown)["shards_done"], 3);
}

#[test]
fn an_add_is_refused_while_the_job_is_run_or_added_to_and_changes_nothing() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let m = manifests(tmp.path(), &[2, 5]);
    let job = tmp.path().join("job");
    ok(&[&["init", s(&job), "--manifest", s(&m[0])][..], &CONFIG].concat());
    let layout = JobLayout::new(&job);
    let manifest = (
        frozen_text(&job),
        std::fs::read(layout.job_file()).unwrap_or_default(),
    );
    for exclusive in [false, true] {
        // A run (or worker) holds the lock shared; another add holds it exclusive.
        let lock = if exclusive {
            JobLock::try_exclusive(&layout).ok().flatten()
        } else {
            JobLock::shared(&layout, || panic!("free")).ok()
        };
        assert!(lock.is_some());
        let out = sparc3d(&["add", s(&job), s(&m[1])]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains("is in use") && err.contains("nothing was added"),
            "{err}"
        );
        let now = (
            frozen_text(&job),
            std::fs::read(layout.job_file()).unwrap_or_default(),
        );
        assert_eq!(now, manifest);
    }

    // A run started while an add holds the lock waits for it, then runs the grown job.
    let lock = JobLock::try_exclusive(&layout).ok().flatten();
    let mut run = Command::new(bin())
        .args(["run", s(&job), "--workers", "2"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("{e}"));
    let mut stderr = run.stderr.take().unwrap_or_else(|| panic!("no stderr"));
    let mut seen = String::new();
    let mut buf = [0u8; 256];
    while !seen.contains("waiting for an `add` to finish") {
        use std::io::Read;
        let n = stderr.read(&mut buf).unwrap_or(0);
        assert!(n > 0, "run ended without waiting: {seen}");
        seen.push_str(&String::from_utf8_lossy(&buf[..n]));
    }
    drop(lock);
    let status = run.wait().unwrap_or_else(|e| panic!("{e}"));
    assert!(status.success());
    assert_eq!(crate::status(&job)["ok"], 2);
}

/// An add stopped after writing its slices and before `job.json` leaves the job as it was:
/// the new files are not pinned, the job runs as before, and the next add adds the rows.
#[test]
fn an_add_stopped_before_its_job_file_leaves_the_job_as_it_was() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let m = manifests(tmp.path(), &[2, 4]);
    let job = tmp.path().join("job");
    ok(&[&["init", s(&job), "--manifest", s(&m[0])][..], &CONFIG].concat());
    let before = std::fs::read(job.join("job.json")).unwrap_or_default();
    add(&job, &m[1]);
    // As if the add had died after writing its slices and page and before job.json.
    std::fs::write(job.join("job.json"), &before).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(status(&job)["items"], 2);
    assert_eq!(manifest_ids(&job).len(), 2);
    let err = add(&job, &m[1]);
    assert!(err.contains("added 2 new items"), "{err}");
    ok(&["run", s(&job), "--workers", "2"]);
    assert_each_item_once(&job);
    assert_eq!(status(&job)["ok"], 4);
}
