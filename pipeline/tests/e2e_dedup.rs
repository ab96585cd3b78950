//! `sparc3d dedup` over a job of generated near-duplicates: a torus moved, re-triangulated
//! and mirrored with jitter is one group with the original as representative; boxes, a
//! cylinder and a sphere of the same extent are in none; `ls` and `export` with
//! `--one-per-group` leave the copies out. A job made without the signature (as every job
//! before it) has no column, and `dedup` says so.

mod common;

use common::{column_names, example, ok, s, shard_files, sparc3d};
use sparcubes::{shapes, TriMesh};
use std::collections::BTreeSet;
use std::path::Path;

/// The meshes, named so that the folder's order puts the original torus first.
fn meshes() -> Vec<(&'static str, TriMesh)> {
    let torus = shapes::torus([0.0; 3], 1.0, 0.35, 48);
    let n = 14f64.sqrt();
    let axis = [1.0 / n, 2.0 / n, 3.0 / n];
    vec![
        ("a_torus.obj", torus.clone()),
        ("b_box.obj", shapes::cuboid([-1.0; 3], [1.0; 3], &[])),
        (
            "c_torus_moved.ply",
            shapes::similar(&torus, axis, 0.7, 3.7, [10.0, -5.0, 2.0]),
        ),
        (
            "d_longer_box.obj",
            shapes::cuboid([-1.0; 3], [1.0, 1.0, 1.3], &[]),
        ),
        ("e_torus_split.obj", shapes::split_at_centroids(&torus)),
        (
            "f_cylinder.obj",
            shapes::cylinder([0.0; 2], 1.0, -1.0, 1.0, 64),
        ),
        (
            "g_torus_mirrored.stl",
            shapes::mirrored_jittered(&torus, 0.002),
        ),
        ("h_sphere.obj", shapes::sphere([0.0; 3], 1.0, 32)),
    ]
}

/// The id of the item converted from the file `name`, from `ls --json`.
fn ids_by_file(job: &str) -> Vec<(String, String)> {
    ok(&["ls", job, "--json"])
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}"));
            let uri = v["uri"].as_str().unwrap_or_default();
            let file = Path::new(uri)
                .file_name()
                .map(|f| f.to_string_lossy().into_owned());
            (
                file.unwrap_or_default(),
                v["id"].as_str().unwrap_or_default().to_string(),
            )
        })
        .collect()
}

#[test]
fn copies_group_with_their_original_and_distinct_shapes_stay_apart() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let dir = tmp.path().join("meshes");
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{e}"));
    for (name, mesh) in meshes() {
        sparcubes::io::save(&mesh, &dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    let job = tmp.path().join("job");
    let j = s(&job);
    ok(&[
        "run",
        s(&dir),
        "--job",
        j,
        "--resolution",
        "96",
        "--workers",
        "2",
    ]);
    let file = std::fs::read_to_string(job.join("job.json")).unwrap_or_else(|e| panic!("{e}"));
    let config: serde_json::Value = serde_json::from_str(&file).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(config["config"]["shape_signature"], true, "{file}");
    for file in shard_files(&job) {
        assert!(column_names(&file).contains(&"shape_signature".to_string()));
    }
    let ids = ids_by_file(j);
    let id = |file: &str| -> String {
        let found = ids
            .iter()
            .find(|(f, _)| f == file)
            .map(|(_, id)| id.clone());
        found.unwrap_or_else(|| panic!("{file} not in {ids:?}"))
    };

    let report: serde_json::Value =
        serde_json::from_str(&ok(&["dedup", j, "--json"])).unwrap_or_else(|e| panic!("{e}"));
    let groups = report["groups"].as_array().cloned().unwrap_or_default();
    assert_eq!(groups.len(), 1, "{report}");
    assert_eq!(
        groups[0]["representative"]["id"],
        id("a_torus.obj"),
        "{report}"
    );
    let members: BTreeSet<String> = groups[0]["members"]
        .as_array()
        .into_iter()
        .flatten()
        .map(|m| {
            let d = m["distance"].as_f64().unwrap_or(f64::NAN);
            assert!((0.0..=0.03).contains(&d), "{m}");
            m["id"].as_str().unwrap_or_default().to_string()
        })
        .collect();
    let copies = [
        "c_torus_moved.ply",
        "e_torus_split.obj",
        "g_torus_mirrored.stl",
    ];
    assert_eq!(members, copies.iter().map(|f| id(f)).collect(), "{report}");
    assert_eq!(report["dropped"].as_array().map(Vec::len), Some(3));

    // The text form names the group, its representative and each member's distance.
    let text = ok(&["dedup", j]);
    assert!(text.starts_with("group 1: 4 items\n"), "{text}");
    assert!(
        text.contains(&format!("\t{}\trepresentative\t", id("a_torus.obj"))),
        "{text}"
    );
    // A threshold of 0 groups only identical signatures: the re-triangulated copy, whose
    // output is the original's (split triangles convert to the same grid), and none of the
    // moved or mirrored copies.
    let exact: serde_json::Value =
        serde_json::from_str(&ok(&["dedup", j, "--threshold", "0", "--json"]))
            .unwrap_or_else(|e| panic!("{e}"));
    let exact_members: Vec<(String, f64)> = exact["groups"]
        .as_array()
        .into_iter()
        .flatten()
        .flat_map(|g| g["members"].as_array().cloned().unwrap_or_default())
        .map(|m| {
            let id = m["id"].as_str().unwrap_or_default().to_string();
            (id, m["distance"].as_f64().unwrap_or(f64::NAN))
        })
        .collect();
    assert!(exact_members.iter().all(|(_, d)| *d == 0.0), "{exact}");
    for moved in ["c_torus_moved.ply", "g_torus_mirrored.stl"] {
        assert!(
            exact_members.iter().all(|(m, _)| *m != id(moved)),
            "{moved}: {exact}"
        );
    }

    // `ls` and `export` keep the representative and every item of no group.
    let out = sparc3d(&["ls", j, "--one-per-group"]);
    let (listed, err) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{err}");
    assert_eq!(listed.lines().count(), 5, "{listed}");
    // The summary counts what is listed and says what `--one-per-group` left out.
    assert!(
        err.contains("--one-per-group: 3 near-duplicates left out"),
        "{err}"
    );
    assert!(err.contains("5 items: 5 ok, 0 failed, 0 pending"), "{err}");
    assert!(copies.iter().all(|f| !listed.contains(&id(f))), "{listed}");

    // Issue 64, item 1: with a `--where` that leaves the representative out, its group is
    // formed among the items that pass: the first copy that passes represents it, and the
    // group keeps exactly one item instead of none.
    let not_the_original = format!("id != '{}'", id("a_torus.obj"));
    let out = sparc3d(&["ls", j, "--where", &not_the_original, "--one-per-group"]);
    let (listed, err) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{err}");
    let kept: Vec<&str> = listed
        .lines()
        .filter_map(|l| l.split('\t').next())
        .collect();
    assert!(kept.contains(&id("c_torus_moved.ply").as_str()), "{listed}");
    assert!(!kept.contains(&id("a_torus.obj").as_str()), "{listed}");
    for dropped in ["e_torus_split.obj", "g_torus_mirrored.stl"] {
        assert!(!kept.contains(&id(dropped).as_str()), "{dropped}: {listed}");
    }
    assert_eq!(
        kept.len(),
        5,
        "the four distinct shapes and one torus: {listed}"
    );
    assert!(err.contains("--where id != '"), "{err}");
    assert!(err.contains("1 items left out"), "{err}");
    assert!(
        err.contains("--one-per-group: 2 near-duplicates left out"),
        "{err}"
    );
    // `export` chooses the same: one torus among the items that pass.
    let filtered = tmp.path().join("export_where");
    let out = sparc3d(&[
        "export",
        j,
        "--format",
        "cubvh",
        "--out",
        s(&filtered),
        "--where",
        &not_the_original,
        "--one-per-group",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("--one-per-group: 2 near-duplicates left out"),
        "{err}"
    );
    let files = std::fs::read_dir(&filtered).map(|d| d.count()).unwrap_or(0);
    assert_eq!(files, 5 + 1, "five items and the export's record");

    let export = tmp.path().join("export");
    let out = sparc3d(&[
        "export",
        j,
        "--format",
        "cubvh",
        "--out",
        s(&export),
        "--one-per-group",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("--one-per-group: 3 near-duplicates left out"),
        "{err}"
    );
    let files = std::fs::read_dir(&export).map(|d| d.count()).unwrap_or(0);
    assert_eq!(files, 5 + 1, "five items and the export's record");
}

#[test]
fn a_job_without_the_signature_has_no_column_and_dedup_says_so() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let dir = tmp.path().join("meshes");
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{e}"));
    for name in ["cube.off", "sphere.obj"] {
        std::fs::copy(example(name), dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    // `shape_signature = false` writes the job.json of every job made before the column.
    let config = tmp.path().join("old.toml");
    std::fs::write(&config, "shape_signature = false\n").unwrap_or_else(|e| panic!("{e}"));
    let job = tmp.path().join("job");
    let j = s(&job);
    let run = ["run", s(&dir), "--job", j, "--config", s(&config)];
    ok(&[&run[..], &["--resolution", "32", "--workers", "1"]].concat());
    let file = std::fs::read_to_string(job.join("job.json")).unwrap_or_else(|e| panic!("{e}"));
    assert!(!file.contains("shape_signature"), "{file}");
    let shards = shard_files(&job);
    assert!(!shards.is_empty());
    for shard in &shards {
        assert!(!column_names(shard).contains(&"shape_signature".to_string()));
    }
    // `dedup` and `--one-per-group` refuse it by name, with what to do, and crash on nothing.
    for args in [vec!["dedup", j], vec!["ls", j, "--one-per-group"]] {
        let out = sparc3d(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("stores no shape signatures"),
            "{args:?}: {err}"
        );
        assert!(
            err.contains("new job") && !err.contains("panicked"),
            "{err}"
        );
    }
    // Everything else reads it as before.
    assert_eq!(ok(&["ls", j]).lines().count(), 2);
}
