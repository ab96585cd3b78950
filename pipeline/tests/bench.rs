//! `sparc3d bench`: every example mesh gives a row per resolution with positive times, the
//! summary has medians, and a mesh that cannot be converted is a failed row, not a failed
//! benchmark. No timing thresholds: these are shared, noisy machines.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples")
}

fn bench_json(args: &[&str]) -> Value {
    let out = Command::new(env!("CARGO_BIN_EXE_sparc3d"))
        .arg("bench")
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("running sparc3d bench {args:?}: {e}"));
    assert!(
        out.status.success(),
        "sparc3d bench {args:?} failed: {}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "bench --json printed no JSON ({e}):\n{}",
            String::from_utf8_lossy(&out.stdout)
        )
    })
}

fn num(v: &Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("{key} missing or not a number in {v}"))
}

#[test]
fn bench_examples_rows_and_summary() {
    let dir = examples();
    let dir_arg = dir.to_string_lossy().into_owned();
    let mut meshes: Vec<String> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| {
            let n = n.to_ascii_lowercase();
            [".stl", ".obj", ".ply", ".off", ".glb", ".gltf"]
                .iter()
                .any(|x| n.ends_with(x))
        })
        .collect();
    meshes.sort();
    assert!(!meshes.is_empty(), "no example meshes in {}", dir.display());

    let report = bench_json(&[&dir_arg, "--resolution", "32,64", "--json"]);
    let rows = report["rows"].as_array().expect("rows array");
    assert_eq!(
        rows.len(),
        meshes.len() * 2,
        "one row per mesh and resolution"
    );
    for res in [32, 64] {
        for name in &meshes {
            let row = rows
                .iter()
                .find(|r| {
                    r["resolution"] == res
                        && r["path"]
                            .as_str()
                            .is_some_and(|p| p.ends_with(name.as_str()))
                })
                .unwrap_or_else(|| panic!("no row for {name} at {res}"));
            assert_eq!(row["ok"], true, "{name} at {res}: {row}");
            assert!(num(row, "total_seconds") > 0.0, "{row}");
            assert!(num(row, "process_seconds") > 0.0, "{row}");
            assert!(num(row, "active_vertices") > 0.0, "{row}");
            assert!(num(row, "output_faces") > 0.0, "{row}");
            assert!(num(row, "bytes_per_active_vertex") > 0.0, "{row}");
            assert!(num(row, "max_rss_bytes") > 0.0, "{row}");
            let stages: Vec<&str> = row["stages"]
                .as_array()
                .expect("stages")
                .iter()
                .filter_map(|s| s[0].as_str())
                .collect();
            for want in ["load", "band", "sign", "deform", "extract", "encode"] {
                assert!(
                    stages.contains(&want),
                    "{name}: no {want} stage in {stages:?}"
                );
            }
        }
    }
    let summary = report["summary"].as_array().expect("summary array");
    assert_eq!(summary.len(), 2);
    for s in summary {
        assert_eq!(num(s, "ok") as usize, meshes.len(), "{s}");
        assert_eq!(num(s, "failed"), 0.0, "{s}");
        assert!(num(&s["total_seconds"], "median") > 0.0, "{s}");
        assert!(num(&s["peak_rss_bytes"], "median") > 0.0, "{s}");
        assert!(num(&s["active_vertices"], "median") > 0.0, "{s}");
        assert!(num(s, "bytes_per_active_vertex_overall") > 0.0, "{s}");
        assert!(!s["stages"].as_array().expect("stages").is_empty(), "{s}");
    }
}

#[test]
fn bench_records_a_broken_mesh_as_failed_and_goes_on() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let good = tmp.path().join("a_cube.off");
    std::fs::copy(examples().join("cube.off"), &good).expect("copy cube.off");
    std::fs::write(tmp.path().join("b_broken.obj"), "this is not a mesh\n").expect("write");
    let out = tmp.path().join("rows.jsonl");
    let report = bench_json(&[
        &tmp.path().to_string_lossy(),
        "--resolution",
        "32",
        "--json",
        "--no-warmup",
        "--out",
        &out.to_string_lossy(),
    ]);
    let rows = report["rows"].as_array().expect("rows array");
    assert_eq!(rows.len(), 2);
    assert_eq!(rows[0]["ok"], true, "{}", rows[0]);
    assert_eq!(rows[1]["ok"], false, "{}", rows[1]);
    let err = rows[1]["error"].as_str().unwrap_or_default();
    assert!(err.contains("b_broken.obj"), "error names the mesh: {err}");
    assert_eq!(report["summary"][0]["failed"], 1);
    let kept = std::fs::read_to_string(&out).expect("rows file");
    assert_eq!(kept.lines().count(), 2, "--out keeps every row");
}

#[test]
fn bench_with_renders_times_the_views_of_each_mesh() {
    let cube = examples().join("cube.off");
    let cube = cube.to_string_lossy().into_owned();
    let report = bench_json(&[
        &cube,
        "--resolution",
        "32",
        "--renders",
        "trellis",
        "--json",
    ]);
    let row = &report["rows"][0];
    assert_eq!(row["ok"], true, "{row}");
    let views = &row["render_views"];
    assert_eq!(views[0], 24, "TRELLIS's 24 views: {row}");
    assert!(views[1].as_f64().is_some_and(|s| s > 0.0), "{row}");
    let stages = row["stages"].as_array().expect("stages");
    assert!(stages.iter().any(|s| s[0] == "renders"), "{row}");
    let summary = &report["summary"][0];
    assert!(
        num(&summary["seconds_per_view"], "median") > 0.0,
        "{summary}"
    );
    // Without the flag: no views and no stage.
    let plain = bench_json(&[&cube, "--resolution", "32", "--json"]);
    assert!(plain["rows"][0].get("render_views").is_none());
}
