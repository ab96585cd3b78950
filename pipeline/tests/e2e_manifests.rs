//! Manifests end to end: what a job keeps of its manifest, and that extra manifest columns add
//! their own shard columns and change nothing else.

mod common;
use common::*;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use sparc3d_schema::row::digest;
use std::path::{Path, PathBuf};

/// The bundled example meshes copied into `dir/meshes`.
fn examples(dir: &Path) -> PathBuf {
    let root = dir.join("meshes");
    std::fs::create_dir_all(&root).unwrap_or_else(|e| panic!("{e}"));
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    for name in [
        "box_textured.glb",
        "cube.off",
        "cube_binary.ply",
        "sphere.obj",
        "wuson.stl",
    ] {
        std::fs::copy(examples.join(name), root.join(name))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    root
}

/// The Arrow batches of one shard file.
fn batches(path: &Path) -> Vec<arrow_array::RecordBatch> {
    let f = std::fs::File::open(path).unwrap_or_else(|e| panic!("{e}"));
    ParquetRecordBatchReaderBuilder::try_new(f)
        .and_then(|b| b.build())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .map(|b| b.unwrap_or_else(|e| panic!("{e}")))
        .collect()
}

/// A job's content digest (as `inspect` computes it: shard digests combined) with every row's
/// `uri` cut to its file name, so that it does not depend on where the test runs, and its
/// provenance kept or dropped.
fn path_free_digest(job: &Path, provenance: bool) -> String {
    let digests: Vec<String> = shard_files(job)
        .iter()
        .map(|p| {
            let mut rows = Vec::new();
            for b in batches(p) {
                rows.extend(
                    sparc3d_schema::columns::arrow::batch_to_rows(&b)
                        .unwrap_or_else(|e| panic!("{e}")),
                );
            }
            for r in &mut rows {
                r.uri = r.uri.rsplit('/').next().unwrap_or_default().to_string();
                if !provenance {
                    r.provenance.clear();
                }
            }
            digest::rows_digest(&rows)
        })
        .collect();
    digest::combine(&digests)
}

/// `sparc3d run INPUT --job JOB` at 32³ in shards of two with `workers` workers, then
/// `extra` flags; returns its output (whether or not it succeeded).
fn run_at_32(input: &Path, job: &Path, workers: &str, extra: &[&str]) -> std::process::Output {
    let base = [
        "run",
        s(input),
        "--job",
        s(job),
        "--resolution",
        "32",
        "--shard-size",
        "2",
    ];
    sparc3d(&[&base[..], &["--workers", workers], extra].concat())
}

/// [`run_at_32`] that must succeed (its stderr shown when it does not).
fn ok_at_32(input: &Path, job: &Path, workers: &str) {
    let out = run_at_32(input, job, workers, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "run {}: {err}", input.display());
}

#[test]
fn extra_columns_add_their_own_columns_and_change_nothing_else() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let meshes = examples(tmp.path());
    let plain = tmp.path().join("plain");
    ok_at_32(&meshes, &plain, "2");
    // The same items in the same order, through a manifest with a licence column.
    let frozen = frozen_text(&plain);
    let mut csv = String::from("path,License\n");
    for line in frozen.lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap_or_else(|e| panic!("{e}"));
        let uri = v["uri"]
            .as_str()
            .unwrap_or_else(|| panic!("no uri in {line}"));
        csv.push_str(&format!("{uri},cc0\n"));
    }
    let manifest = tmp.path().join("m.csv");
    std::fs::write(&manifest, csv).unwrap_or_else(|e| panic!("{e}"));
    let licensed = tmp.path().join("licensed");
    ok_at_32(&manifest, &licensed, "2");

    // Without provenance the rows hash the same: conversion and storage are untouched.
    assert_eq!(
        path_free_digest(&plain, false),
        path_free_digest(&licensed, false)
    );
    assert_ne!(
        path_free_digest(&plain, true),
        path_free_digest(&licensed, true)
    );
    // The columns of a job with the default config (the quality columns on).
    let sections =
        sparc3d_schema::columns::arrow::Sections::of(&sparc3d_schema::JobConfig::default());
    let before: Vec<String> = sparc3d_schema::columns::arrow::schema_for(&[], sections)
        .fields()
        .iter()
        .map(|f| f.name().clone())
        .collect();
    let with_licence: Vec<String> = before
        .iter()
        .cloned()
        .chain(["manifest.license".to_string()]) // names are lower-cased (FORMAT.md)
        .collect();
    for (job, want) in [(&plain, &before), (&licensed, &with_licence)] {
        let files = shard_files(job);
        assert_eq!(files.len(), 3);
        for f in &files {
            assert_eq!(&column_names(f), want, "{}", f.display());
        }
    }
}

/// A manifest over the examples (and one broken file) with provenance columns: a licence, a
/// name (one with a comma, one empty), a uid and a source URL in a second path-like column.
fn provenance_manifest(dir: &Path) -> PathBuf {
    let meshes = examples(dir);
    std::fs::write(meshes.join("broken.obj"), "not a mesh\n").unwrap_or_else(|e| panic!("{e}"));
    let m = dir.join("m.csv");
    let rows = [
        "local_path,uri,License,name,uid",
        "meshes/cube.off,https://h/cube.off,cc0,Cube,u1",
        "meshes/sphere.obj,https://h/sphere.obj,cc-by,\"Sphere, round\",u2",
        "meshes/wuson.stl,https://h/wuson.stl,by-nc,Wuson,u3",
        "meshes/box_textured.glb,https://h/box.glb,cc-by,,u4",
        "meshes/broken.obj,https://h/broken.obj,cc0,Broken,u5",
    ];
    std::fs::write(&m, rows.join("\n") + "\n").unwrap_or_else(|e| panic!("{e}"));
    m
}

/// Every `manifest.*` column of a row with its value (None: null).
type Provenance = Vec<(String, Option<String>)>;

/// (id, provenance) of each row of a job, in shard order.
fn provenance_of_rows(job: &Path) -> Vec<(String, Provenance)> {
    use arrow_array::{Array, StringArray};
    let mut out = Vec::new();
    for file in shard_files(job) {
        for b in batches(&file) {
            let schema = b.schema();
            let strings = |name: &str| -> StringArray {
                b.column_by_name(name)
                    .and_then(|c| c.as_any().downcast_ref::<StringArray>().cloned())
                    .unwrap_or_else(|| panic!("{name} is not a string column"))
            };
            let ids = strings("id");
            let names: Vec<String> = schema
                .fields()
                .iter()
                .map(|f| f.name().clone())
                .filter(|n| n.starts_with("manifest."))
                .collect();
            for i in 0..b.num_rows() {
                let values = names
                    .iter()
                    .map(|n| {
                        let c = strings(n);
                        (n.clone(), c.is_valid(i).then(|| c.value(i).to_string()))
                    })
                    .collect();
                out.push((ids.value(i).to_string(), values));
            }
        }
    }
    out
}

#[test]
fn provenance_columns_come_through_to_shards_listings_and_exports() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let m = provenance_manifest(tmp.path());
    let job = tmp.path().join("job");
    let out = run_at_32(&m, &job, "2", &["--where", "license in (cc-by, cc0)"]);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(err.contains("4 rows kept, 1 left out"), "{err}");
    assert!(
        err.contains("provenance columns kept with every item: license, name, uid, uri"),
        "{err}"
    );

    // Shards: one nullable string column per manifest column, null where the row had none.
    let rows = provenance_of_rows(&job);
    assert_eq!(rows.len(), 4);
    let col = |v: &[(String, Option<String>)], k: &str| -> Option<String> {
        v.iter().find(|(n, _)| n == k).and_then(|(_, x)| x.clone())
    };
    let names: Vec<String> = rows[0].1.iter().map(|(n, _)| n.clone()).collect();
    assert_eq!(
        names,
        [
            "manifest.license",
            "manifest.name",
            "manifest.uid",
            "manifest.uri"
        ]
    );
    let licences: Vec<Option<String>> = rows
        .iter()
        .map(|(_, v)| col(v, "manifest.license"))
        .collect();
    assert_eq!(
        licences,
        [Some("cc0"), Some("cc-by"), Some("cc-by"), Some("cc0")].map(|s| s.map(String::from))
    );
    assert_eq!(
        col(&rows[1].1, "manifest.name").as_deref(),
        Some("Sphere, round")
    );
    assert_eq!(
        col(&rows[2].1, "manifest.name"),
        None,
        "an empty value is null"
    );
    assert_eq!(
        col(&rows[3].1, "manifest.uri").as_deref(),
        Some("https://h/broken.obj")
    );

    // ls and failures: `name=value` fields after the fixed ones; --json: a `manifest` object.
    let ls = ok(&["ls", s(&job)]);
    let first = ls.lines().next().unwrap_or_default();
    assert!(
        first.ends_with("\tlicense=cc0\tname=Cube\tuid=u1\turi=https://h/cube.off"),
        "{first}"
    );
    let json: serde_json::Value = serde_json::from_str(
        ok(&["ls", s(&job), "--json"])
            .lines()
            .nth(1)
            .unwrap_or_default(),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(json["manifest"]["name"], "Sphere, round");
    let failures = ok(&["failures", s(&job)]);
    assert!(
        failures.starts_with("parse_error\t")
            && failures.contains("\tlicense=cc0\tname=Broken\tuid=u5\t"),
        "{failures}"
    );

    // inspect counts rows per value; the report has a section per column.
    let inspect = inspect(&job);
    assert_eq!(inspect["provenance"]["license"]["cc-by"], 2);
    assert_eq!(inspect["provenance"]["name"][""], 1);
    let report = tmp.path().join("report.html");
    ok(&["report", s(&job), "-o", s(&report), "--previews", "0"]);
    let html = std::fs::read_to_string(&report).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        html.contains("<h3>manifest.license</h3>") && html.contains("license=cc0; name=Broken"),
        "report"
    );

    // Exports list them with each item.
    let export = tmp.path().join("export");
    ok(&["export", s(&job), "--format", "cubvh", "--out", s(&export)]);
    let record = std::fs::read_to_string(export.join(".sparc3d-export.json"))
        .unwrap_or_else(|e| panic!("{e}"));
    let record: serde_json::Value = serde_json::from_str(&record).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(record["items"][0]["manifest"]["license"], "cc0");
    assert_eq!(record["items"][1]["manifest"]["uid"], "u2");
}

#[test]
fn provenance_jobs_are_deterministic_whatever_the_worker_count() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let m = provenance_manifest(tmp.path());
    let digests: Vec<String> = ["1", "3"]
        .iter()
        .map(|workers| {
            let job = tmp.path().join(format!("job-{workers}"));
            ok_at_32(&m, &job, workers);
            inspect(&job)["content_digest"]
                .as_str()
                .unwrap_or_default()
                .to_string()
        })
        .collect();
    assert_eq!(digests[0], digests[1]);
    // The provenance is part of the content: the same meshes without it digest otherwise.
    let plain = tmp.path().join("plain.csv");
    let text = std::fs::read_to_string(&m).unwrap_or_else(|e| panic!("{e}"));
    let paths: Vec<&str> = text
        .lines()
        .map(|l| l.split(',').next().unwrap_or_default())
        .collect();
    std::fs::write(&plain, paths.join("\n") + "\n").unwrap_or_else(|e| panic!("{e}"));
    let job = tmp.path().join("job-plain");
    ok_at_32(&plain, &job, "2");
    assert_ne!(inspect(&job)["content_digest"], digests[0].as_str());
}

/// `dir/NAME/`: one box OBJ whose material library maps `t.png`, holding `texture`.
fn variant(dir: &Path, name: &str, texture: &[u8]) {
    let folder = dir.join(name);
    std::fs::create_dir_all(&folder).unwrap_or_else(|e| panic!("{e}"));
    let (v, f) = boxed([1.0, 0.6, 0.4], [0.0; 3]);
    let obj = folder.join("m.obj");
    write_obj(&obj, &v, &f);
    let text = std::fs::read_to_string(&obj).unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(&obj, format!("mtllib m.mtl\nusemtl paint\n{text}"))
        .unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(folder.join("m.mtl"), "newmtl paint\nmap_Kd t.png\n")
        .unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(folder.join("t.png"), texture).unwrap_or_else(|e| panic!("{e}"));
}

/// Issue 64 item 3: colour variants (one OBJ file, different textures) are two items to
/// `manifest build` and `run DIR`, a copy of a whole folder is still one, and TRELLIS.2's
/// export names each variant's files by its own key.
#[test]
fn colour_variants_of_one_mesh_file_are_distinct_items() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let meshes = dir.path().join("meshes");
    variant(&meshes, "red", b"red texels");
    variant(&meshes, "blue", b"blue texels");
    variant(&meshes, "red_copy", b"red texels");
    let m = dir.path().join("m.csv");
    let built = sparc3d(&["manifest", "build", s(&meshes), "-o", s(&m)]);
    let said = String::from_utf8_lossy(&built.stderr);
    assert!(built.status.success(), "{said}");
    assert!(said.contains("1 identical duplicates left out"), "{said}");
    let job = dir.path().join("job");
    ok(&["init", s(&job), "--manifest", s(&m), "--for", "trellis2@48"]);
    let ids = manifest_ids(&job);
    assert_eq!(ids.len(), 2, "{ids:?}");
    assert_ne!(ids[0], ids[1]);
    let sha = |id: &str| id.split('-').next().map(str::to_string);
    assert_eq!(sha(&ids[0]), sha(&ids[1]), "one mesh file: {ids:?}");
    ok(&["run", s(&job), "--workers", "1"]);
    assert_eq!(status(&job)["ok"], 2);
    let out = dir.path().join("t2");
    ok(&["export", s(&job), "--format", "trellis2", "--out", s(&out)]);
    let mut keys: Vec<String> = std::fs::read_dir(out.join("dual_grid_48"))
        .unwrap_or_else(|e| panic!("{e}"))
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            name.strip_suffix(".vxz").map(str::to_string)
        })
        .collect();
    keys.sort();
    let mut want = ids.clone();
    want.sort();
    assert_eq!(keys, want);
    let direct = dir.path().join("direct");
    let run = sparc3d(&["run", s(&meshes), "--job", s(&direct), "--resolution", "32"]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert_eq!(status(&direct)["ok"], 2);
}

/// A mesh that names no other file keeps its sha256 as its id, as before.
#[test]
fn a_mesh_that_names_no_file_is_identified_by_its_sha256() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let meshes = examples(dir.path());
    let m = dir.path().join("m.csv");
    ok(&["manifest", "build", s(&meshes), "-o", s(&m)]);
    let job = dir.path().join("job");
    ok(&["init", s(&job), "--manifest", s(&m)]);
    for (id, name) in manifest_ids(&job)
        .iter()
        .zip(["box_textured.glb", "cube.off"])
    {
        let bytes = std::fs::read(meshes.join(name)).unwrap_or_else(|e| panic!("{e}"));
        use sha2::Digest;
        let sha = sparc3d_schema::hex::hex(&sha2::Sha256::digest(&bytes));
        assert_eq!(*id, sha, "{name}");
    }
}
