//! The quality columns and `--where` over a job's rows, end to end: six generated meshes whose
//! faces, topology, bounds and licences are known by hand, one broken file, and the answers of
//! `ls`, `export` and `inspect --where` against them; and a job made without the quality
//! columns (as every job before them) that resumes, reads and filters.

mod common;
use common::*;
use sparc3d_schema::ShardRow;
use sparc3d_workers::store::read::read_rows;
use std::path::{Path, PathBuf};

type Mesh = (Vec<[f64; 3]>, Vec<[usize; 3]>);

/// The meshes (id, mesh, licence) and a broken file, written with a manifest; returns it.
///
/// - `boxa`: a 2 × 1 × 0.5 box: 12 faces, closed, aspect 4, area 7, volume 1.
/// - `boxb`: a unit box with one face repeated (dropped at load) and a zero-area triangle of
///   three new collinear vertices inside: 13 faces, 1 duplicate, 1 degenerate, 3 boundary
///   edges (the sliver's), 2 components.
/// - `sphere6`, `sphere10`: 120 and 360 faces, closed.
/// - `sheet`: a flat unit square of 2 triangles: 4 boundary edges, aspect inf; no licence.
/// - `fins`: three triangles on one edge: 1 non-manifold edge, 6 boundary edges.
fn corpus(dir: &Path) -> PathBuf {
    let meshes = dir.join("meshes");
    std::fs::create_dir_all(&meshes).unwrap_or_else(|e| panic!("{e}"));
    let mut boxb = boxed([1.0; 3], [0.0; 3]);
    boxb.1.push([2, 1, 0]);
    boxb.0
        .extend([[0.5, 0.5, 0.5], [0.6, 0.5, 0.5], [0.7, 0.5, 0.5]]);
    boxb.1.push([8, 9, 10]);
    let sheet = (
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    );
    let fins = (
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, 1.0, 0.0],
            [0.5, -1.0, 0.0],
            [0.5, 0.0, 1.0],
        ],
        vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
    );
    let items: [(&str, Mesh, &str); 6] = [
        ("boxa", boxed([2.0, 1.0, 0.5], [0.0; 3]), "cc0"),
        ("boxb", boxb, "cc-by"),
        ("sphere6", sphere(6, 1.0), "cc0"),
        ("sphere10", sphere(10, 1.0), "by-nc"),
        ("sheet", sheet, ""),
        ("fins", fins, "cc-by-sa"),
    ];
    let mut csv = String::from("path,id,license\n");
    for (id, mesh, license) in &items {
        write_obj(&meshes.join(format!("{id}.obj")), &mesh.0, &mesh.1);
        csv.push_str(&format!("meshes/{id}.obj,{id},{license}\n"));
    }
    std::fs::write(meshes.join("broken.obj"), "not a mesh\n").unwrap_or_else(|e| panic!("{e}"));
    csv.push_str("meshes/broken.obj,broken,cc0\n");
    let manifest = dir.join("m.csv");
    std::fs::write(&manifest, csv).unwrap_or_else(|e| panic!("{e}"));
    manifest
}

/// Runs `m` into `job` at 32³, three items a shard, with `extra` arguments.
fn run_job(m: &Path, job: &Path, extra: &[&str]) {
    let base = ["run", s(m), "--job", s(job), "--resolution", "32"];
    let rest = ["--shard-size", "3", "--workers", "1"];
    let out = sparc3d(&[&base[..], &rest, extra].concat());
    // The broken file fails its item, so the run exits 1 with every other item converted.
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("7 items"), "{err}");
}

/// The ids `ls --where FILTER` lists, in order.
fn ls_ids(job: &Path, filter: &str) -> Vec<String> {
    let out = ok(&["ls", s(job), "--where", filter]);
    out.lines()
        .filter_map(|l| l.split('\t').next())
        .map(str::to_string)
        .collect()
}

/// The stderr of a command that must fail.
fn refused(args: &[&str]) -> String {
    let out = sparc3d(args);
    assert!(!out.status.success(), "{args:?} passed");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Every row of a job's shards, in shard order.
fn rows(job: &Path) -> Vec<ShardRow> {
    let read = |p: &PathBuf| read_rows(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    shard_files(job).iter().flat_map(read).collect()
}

#[test]
fn quality_columns_hold_what_each_mesh_is() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let m = corpus(tmp.path());
    let job = tmp.path().join("job");
    run_job(&m, &job, &[]);
    let rows = rows(&job);
    let row = |id: &str| {
        rows.iter()
            .find(|r| r.id == id)
            .unwrap_or_else(|| panic!("{id}"))
    };
    let quality = |id| {
        row(id)
            .quality
            .clone()
            .unwrap_or_else(|| panic!("{id}: no facts"))
    };
    // Counts, by hand (see `corpus`): faces, components, boundary, non-manifold,
    // degenerate and duplicate.
    let counts = |id| {
        let q = quality(id);
        let k = row(id).counts.clone().unwrap_or_default();
        let components = k.input_components.unwrap_or(0);
        [
            k.input_faces,
            components,
            q.boundary_edges,
            q.non_manifold_edges,
        ]
        .into_iter()
        .chain([q.degenerate_faces, q.duplicate_faces])
        .collect::<Vec<u64>>()
    };
    assert_eq!(counts("boxa"), [12, 1, 0, 0, 0, 0]);
    assert_eq!(counts("boxb"), [13, 2, 3, 0, 1, 1]);
    assert_eq!(counts("sphere10"), [360, 1, 0, 0, 0, 0]);
    assert_eq!(counts("sheet"), [2, 1, 4, 0, 0, 0]);
    assert_eq!(counts("fins"), [3, 1, 6, 1, 0, 0]);
    assert_eq!(quality("boxa").extent, [2.0, 1.0, 0.5]);
    assert_eq!(quality("sheet").extent, [1.0, 1.0, 0.0]);
    assert_eq!(quality("boxa").aspect(), Some(4.0));
    assert_eq!(quality("sheet").aspect(), Some(f64::INFINITY));
    let area = |id| quality(id).surface_area;
    assert_eq!((area("boxa"), area("sheet")), (7.0, 1.0));
    // The output encloses about the box's volume (1) at 32³, in the source's units; one
    // closed component.
    let v = quality("boxa").output_volume.unwrap_or(f64::NAN);
    assert!((v - 1.0).abs() < 0.1, "boxa volume {v}");
    assert_eq!(quality("boxa").output_components, Some(1));
    // The sheet is all thin shell around its open surface.
    let sheet = row("sheet").counts.clone().unwrap_or_default();
    assert!(sheet.shell_vertices > 0, "{sheet:?}");
    // The broken file's row has no facts; every shard has the columns.
    assert_eq!(row("broken").quality, None);
    for file in shard_files(&job) {
        assert!(column_names(&file).contains(&"shell_share".to_string()));
    }
}

#[test]
fn where_chooses_the_rows_ls_export_and_inspect_read() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let m = corpus(tmp.path());
    let job = tmp.path().join("job");
    run_job(&m, &job, &[]);
    for (filter, want) in [
        (
            "input_faces <= 100 and license in (cc0, cc-by)",
            &["boxa", "boxb"][..],
        ),
        ("aspect >= 4", &["boxa", "sheet"]),
        ("input_non_manifold_edges > 0", &["fins"]),
        (
            "input_boundary_edges = 0 and input_degenerate_faces = 0",
            &["boxa", "sphere6", "sphere10"],
        ),
        ("license != cc0", &["boxb", "sphere10", "sheet", "fins"]),
        ("status = failed", &["broken"]),
        (
            "Input_Faces > 100 AND shell_share < 0.5",
            &["sphere6", "sphere10"],
        ),
    ] {
        assert_eq!(ls_ids(&job, filter), want, "ls --where {filter}");
    }
    assert_eq!(ls_ids(&job, "resolution = 32.0").len(), 7);

    // export: only the matching ok items are written.
    let out = tmp.path().join("export");
    let args = ["export", s(&job), "--format", "cubvh", "--out", s(&out)];
    ok(&[&args[..], &["--where", "input_faces >= 100"]].concat());
    let record: serde_json::Value = serde_json::from_slice(
        &std::fs::read(out.join(".sparc3d-export.json")).unwrap_or_else(|e| panic!("{e}")),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let ids: Vec<&str> = record["items"]
        .as_array()
        .map(|a| a.iter().filter_map(|i| i["id"].as_str()).collect())
        .unwrap_or_default();
    assert_eq!(ids, ["sphere6", "sphere10"]);
    assert_eq!(record["where"], "input_faces >= 100");
    let npz = std::fs::read_dir(&out).map(|d| d.count()).unwrap_or(0);
    assert_eq!(npz, 3, "two items and the record");

    // inspect: the rows that pass, and how many did not.
    let text = ok(&["inspect", s(&job), "--json", "--where", "license = cc0"]);
    let report: serde_json::Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        [&report["rows"], &report["ok"], &report["failed"]],
        [3, 2, 1]
    );
    assert_eq!(report["filter"]["rows_left_out"], 4);
    assert_eq!(report["provenance"]["license"]["cc0"], 3);
    // One shard file alone reads its own columns.
    let shard = job.join("shards").join("part-00000.parquet");
    let text = ok(&[
        "inspect",
        s(&shard),
        "--json",
        "--where",
        "input_faces < 50",
    ]);
    let report: serde_json::Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((&report["rows"], &report["ok"]), (&2.into(), &2.into()));
}

#[test]
fn bad_filters_are_refused_naming_the_column_or_value() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let m = corpus(tmp.path());
    let job = tmp.path().join("job");
    run_job(&m, &job, &[]);
    let out = tmp.path().join("export");
    for (filter, said) in [
        ("licence = cc0", "the job has no column \"licence\""),
        ("input_faces < many", "\"many\" is not a number"),
        ("license >= 3", "the column license holds text"),
        (
            "input_faces = twelve",
            "holds numbers, and \"twelve\" is not a number",
        ),
    ] {
        for args in [
            vec!["ls", s(&job)],
            vec!["inspect", s(&job)],
            vec!["export", s(&job), "--format", "cubvh", "--out", s(&out)],
        ] {
            let err = refused(&[&args[..], &["--where", filter]].concat());
            assert!(err.contains(said), "{args:?} --where {filter}: {err}");
        }
    }
    let err = refused(&["ls", s(&job), "--where", "licence = cc0"]);
    assert!(
        err.contains("license") && err.contains("input_faces"),
        "{err}"
    );
    assert!(!out.exists(), "nothing exported");
}

#[test]
fn a_job_without_quality_columns_resumes_reads_and_filters_on_what_it_has() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let m = corpus(tmp.path());
    let job = tmp.path().join("job");
    // `quality = false` writes the job.json of every job made before the columns existed.
    std::fs::write(tmp.path().join("old.toml"), "quality = false\n")
        .unwrap_or_else(|e| panic!("{e}"));
    let config = tmp.path().join("old.toml");
    let init = ["init", s(&job), "--manifest", s(&m), "--config", s(&config)];
    ok(&[&init[..], &["--resolution", "32", "--shard-size", "3"]].concat());
    let file = std::fs::read_to_string(job.join("job.json")).unwrap_or_else(|e| panic!("{e}"));
    assert!(!file.contains("quality"), "{file}");
    // One shard, then the rest: the job resumes.
    ok(&["work", s(&job), "--shard-index", "0"]);
    let out = sparc3d(&["run", s(&job), "--workers", "1"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("4 items in"), "{err}");
    assert!(err.contains("6 ok, 1 failed in total"), "{err}");
    assert_eq!(rows(&job).len(), 7);
    assert!(rows(&job).iter().all(|r| r.quality.is_none()));
    for file in shard_files(&job) {
        let names = column_names(&file);
        assert!(names.contains(&"input_faces".to_string()));
        assert!(!names
            .iter()
            .any(|n| n == "aspect" || n == "input_boundary_edges"));
    }
    assert_eq!(ls_ids(&job, "input_faces > 100"), ["sphere6", "sphere10"]);
    let err = refused(&["ls", s(&job), "--where", "aspect > 1"]);
    assert!(err.contains("no column \"aspect\""), "{err}");
    ok(&["inspect", s(&job)]);
}
