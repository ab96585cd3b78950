//! End to end, the newcomer's path on the bundled real meshes: one `run DIR --job OUT` from a
//! folder to a finished job (and resumed), items found by id prefix or file name with hints on
//! a miss, `ls`, failures pointed to by `run`, `status` and `ls`, how `validate` finds its
//! Python, and the defaults `run --help` shows.

mod common;

use common::*;
use std::path::{Path, PathBuf};
use std::process::Output;

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The bundled example meshes (real files, with their licences in examples/LICENSES.md).
fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples")
}

/// A folder with a copy of every bundled example mesh, plus `extra` (name, content) files.
fn meshes(tmp: &Path, extra: &[(&str, &[u8])]) -> PathBuf {
    let dir = tmp.join("meshes");
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{e}"));
    for e in std::fs::read_dir(examples())
        .unwrap_or_else(|e| panic!("{e}"))
        .flatten()
    {
        if sparcubes::io::Format::from_extension(&e.path()).is_some() {
            std::fs::copy(e.path(), dir.join(e.file_name())).unwrap_or_else(|e| panic!("{e}"));
        }
    }
    for (name, bytes) in extra {
        let path = dir.join(name);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).unwrap_or_else(|e| panic!("{e}"));
        }
        std::fs::write(path, bytes).unwrap_or_else(|e| panic!("{e}"));
    }
    dir
}

/// Number of mesh files among the bundled examples.
fn example_count() -> usize {
    std::fs::read_dir(examples())
        .map(|d| {
            d.flatten()
                .filter(|e| sparcubes::io::Format::from_extension(&e.path()).is_some())
                .count()
        })
        .unwrap_or(0)
}

/// `run DIR --job OUT` at a small resolution; returns its output.
fn run_dir(input: &Path, job: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["run", s(input), "--job", s(job), "--resolution", "32"];
    args.extend_from_slice(extra);
    sparc3d(&args)
}

/// The id of the item whose source ends with `name`, from the job's frozen manifest.
fn id_of(job: &Path, name: &str) -> String {
    let text = frozen_text(job);
    text.lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find(|v| v["uri"].as_str().is_some_and(|u| u.ends_with(name)))
        .and_then(|v| v["id"].as_str().map(str::to_string))
        .unwrap_or_else(|| panic!("{name} not in the manifest of {}", job.display()))
}

#[test]
fn one_run_makes_the_job_from_a_folder_and_the_next_resumes_it() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let dir = meshes(tmp.path(), &[]);
    let job = tmp.path().join("out/job");
    let out = run_dir(&dir, &job, &["--workers", "2"]);
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    let st = status(&job);
    assert_eq!(st["items"], example_count() as u64, "{st}");
    assert_eq!(st["ok"], example_count() as u64, "{st}");
    // Where the shards are and what to run next; no failures to point to.
    assert!(
        err.contains(&format!("shards: {}", s(&job.join("shards")))),
        "{err}"
    );
    for next in ["status", "ls", "inspect", "show", "report"] {
        assert!(
            err.contains(&format!("sparc3d {next} {}", s(&job))),
            "{next}: {err}"
        );
    }
    assert!(!err.contains("sparc3d failures"), "{err}");
    let digest = inspect(&job)["content_digest"].clone();

    // The same command again resumes (nothing left to do), and `run JOB` still works.
    let again = run_dir(&dir, &job, &[]);
    assert!(again.status.success(), "{}", stderr(&again));
    assert!(stderr(&again).contains("resuming"), "{}", stderr(&again));
    ok(&["run", s(&job)]);
    assert_eq!(inspect(&job)["content_digest"], digest);

    // A manifest works as input too, and gives the same content.
    let manifest = tmp.path().join("m.csv");
    ok(&["manifest", "build", s(&dir), "-o", s(&manifest)]);
    let from_manifest = tmp.path().join("from-manifest");
    let out = run_dir(&manifest, &from_manifest, &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(inspect(&from_manifest)["content_digest"], digest);

    // Another config for the existing job is refused by key; a folder alone is not a job.
    let out = sparc3d(&["run", s(&dir), "--job", s(&job), "--resolution", "64"]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("params.resolution"),
        "{}",
        stderr(&out)
    );
    let out = sparc3d(&["run", s(&dir)]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains(&format!("sparc3d run {} --job OUT", s(&dir))),
        "{}",
        stderr(&out)
    );
}

#[test]
fn ids_are_found_by_prefix_or_source_and_misses_suggest() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let sphere = std::fs::read(examples().join("sphere.obj")).unwrap_or_else(|e| panic!("{e}"));
    // The same sphere in two files of the same name (their bytes differ, so both are kept).
    let mut sphere_a = sphere.clone();
    sphere_a.extend_from_slice(b"\n# copy a\n");
    let mut sphere_b = sphere;
    sphere_b.extend_from_slice(b"\n# copy b\n");
    let dir = meshes(
        tmp.path(),
        &[
            ("a/part.obj", &sphere_a),
            ("b/part.obj", &sphere_b),
            ("broken.obj", b"this is not a mesh\n"),
        ],
    );
    let job = tmp.path().join("job");
    let out = run_dir(&dir, &job, &["--workers", "2"]);
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    let j = s(&job);

    // Failures are pointed to: the last line of `run`, `status` and `ls`.
    let last = err.lines().last().unwrap_or("");
    assert!(last.contains(&format!("sparc3d failures {j}")), "{err}");
    assert!(ok(&["status", j]).contains(&format!("sparc3d failures {j}")));

    // `ls`: every item with id, status and source; --failed and --json.
    let wuson = id_of(&job, "/wuson.stl");
    let listed = ok(&["ls", j]);
    assert_eq!(listed.lines().count(), example_count() + 3, "{listed}");
    assert!(
        listed.contains(&format!("{wuson}\tok\t")) && listed.contains("failed:parse_error"),
        "{listed}"
    );
    let failed = ok(&["ls", j, "--failed", "--json"]);
    let rows: Vec<serde_json::Value> = failed
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect();
    assert_eq!(rows.len(), 1, "{failed}");
    assert_eq!(rows[0]["status"], "failed");
    assert_eq!(rows[0]["error_class"], "parse_error");
    assert!(rows[0]["uri"]
        .as_str()
        .is_some_and(|u| u.ends_with("broken.obj")));

    // The whole id, a prefix, the file name and the path give the same mesh.
    let shown = |id: &str, name: &str| {
        let path = tmp.path().join(name);
        ok(&["show", j, "--id", id, "-o", s(&path)]);
        std::fs::read(&path).unwrap_or_else(|e| panic!("{e}"))
    };
    let whole = shown(&wuson, "whole.ply");
    assert_eq!(shown(&wuson[..8], "prefix.ply"), whole);
    assert_eq!(shown("wuson.stl", "name.ply"), whole);
    assert_eq!(shown(s(&dir.join("wuson.stl")), "path.ply"), whole);
    assert_eq!(
        shown("b/part.obj", "b.ply").len(),
        shown("a/part.obj", "a.ply").len()
    );

    // A typo suggests the item; a shared name is ambiguous and lists both.
    let show_err = |id: &str| {
        let out = sparc3d(&["show", j, "--id", id, "-o", s(&tmp.path().join("x.ply"))]);
        assert!(!out.status.success(), "--id {id} should fail");
        stderr(&out)
    };
    let mut typo = wuson[..12].to_string();
    let last = if typo.ends_with('0') { "1" } else { "0" };
    typo.replace_range(11.., last);
    let err = show_err(&typo);
    assert!(
        err.contains("closest") && err.contains(&wuson) && err.contains(&format!("sparc3d ls {j}")),
        "{err}"
    );
    let err = show_err("wusn.stl");
    assert!(err.contains("closest") && err.contains(&wuson), "{err}");
    let err = show_err("part.obj");
    assert!(
        err.contains("ambiguous") && err.contains("a/part.obj") && err.contains("b/part.obj"),
        "{err}"
    );

    // `preview` finds items the same way.
    let png = tmp.path().join("p.png");
    let out = sparc3d(&[
        "preview",
        j,
        "--id",
        "wuson.stl",
        "-o",
        s(&png),
        "--views",
        "1",
        "--tile",
        "64",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stderr(&out).contains(&wuson), "{}", stderr(&out));

    // `export --ids` too: a file name and a prefix give those items' files, nothing else.
    let sphere_a = id_of(&job, "a/part.obj");
    let export = tmp.path().join("export");
    let ids = format!("wuson.stl,{}", &sphere_a[..10]);
    let out = sparc3d(&[
        "export",
        j,
        "--format",
        "cubvh",
        "--out",
        s(&export),
        "--ids",
        &ids,
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let mut files: Vec<String> = std::fs::read_dir(&export)
        .unwrap_or_else(|e| panic!("{e}"))
        .map(|e| {
            e.unwrap_or_else(|e| panic!("{e}"))
                .file_name()
                .to_string_lossy()
                .into_owned()
        })
        .filter(|name| name != ".sparc3d-export.json")
        .collect();
    // Named `<manifest index>-<id>.npz` (docs/FORMAT.md, "Exports").
    files.sort();
    assert_eq!(files.len(), 2, "{files:?}");
    for id in [&wuson, &sphere_a] {
        let suffix = format!("-{id}.npz");
        assert!(
            files.iter().any(|f| f.ends_with(&suffix)),
            "{id}: {files:?}"
        );
    }
    // A typo is refused before anything is written, with the closest item; so is a shared name.
    let export_err = |ids: &str| {
        let out_dir = tmp.path().join("export-miss");
        let out = sparc3d(&[
            "export",
            j,
            "--format",
            "cubvh",
            "--out",
            s(&out_dir),
            "--ids",
            ids,
        ]);
        assert!(!out.status.success(), "--ids {ids} should fail");
        assert!(!out_dir.exists(), "--ids {ids} wrote {}", out_dir.display());
        stderr(&out)
    };
    let err = export_err(&format!("{wuson},wusn.stl"));
    assert!(err.contains("closest") && err.contains(&wuson), "{err}");
    let err = export_err("part.obj");
    assert!(
        err.contains("ambiguous") && err.contains("a/part.obj"),
        "{err}"
    );
}

#[test]
fn an_ambiguous_id_prefix_lists_the_matches() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let ex = examples();
    let manifest = tmp.path().join("m.csv");
    std::fs::write(
        &manifest,
        format!(
            "id,path\ncube-off,{}\ncube-ply,{}\nsphere,{}\n",
            s(&ex.join("cube.off")),
            s(&ex.join("cube_binary.ply")),
            s(&ex.join("sphere.obj"))
        ),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let job = tmp.path().join("job");
    let out = run_dir(&manifest, &job, &["--workers", "1"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let out = sparc3d(&[
        "show",
        s(&job),
        "--id",
        "cube",
        "-o",
        s(&tmp.path().join("x.ply")),
    ]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("ambiguous") && err.contains("cube-off") && err.contains("cube-ply"),
        "{err}"
    );
    ok(&[
        "show",
        s(&job),
        "--id",
        "cube-p",
        "-o",
        s(&tmp.path().join("y.ply")),
    ]);
}

/// A stand-in for a Python with pymeshlab: imports succeed, the probe prints `{}` and every
/// item passes. Written as a virtual environment's `bin/python`.
fn fake_python(venv: &Path) -> PathBuf {
    let bin = venv.join("bin");
    std::fs::create_dir_all(&bin).unwrap_or_else(|e| panic!("{e}"));
    let python = bin.join("python");
    std::fs::write(
        &python,
        "#!/bin/sh\n\
         [ \"$1\" = -c ] && exit 0\n\
         [ \"$2\" = --probe ] && { echo '{}'; exit 0; }\n\
         while read -r line; do echo '{\"ok\": true, \"checks\": {}, \"measures\": {}}'; done\n",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&python, std::fs::Permissions::from_mode(0o755))
        .unwrap_or_else(|e| panic!("{e}"));
    python
}

#[test]
fn validate_finds_the_interpreter_as_documented_and_samples_all_of_a_small_job() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let dir = meshes(tmp.path(), &[]);
    let job = tmp.path().join("job");
    let out = run_dir(&dir, &job, &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    // A .venv next to the job that cannot import pymeshlab, an active one that can.
    let broken = tmp.path().join(".venv/bin/python");
    std::fs::create_dir_all(tmp.path().join(".venv/bin")).unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(&broken, "#!/bin/sh\nexit 1\n").unwrap_or_else(|e| panic!("{e}"));
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&broken, std::fs::Permissions::from_mode(0o755))
        .unwrap_or_else(|e| panic!("{e}"));
    let active = fake_python(&tmp.path().join("active"));
    let empty_path = tmp.path().join("empty-bin");
    std::fs::create_dir_all(&empty_path).unwrap_or_else(|e| panic!("{e}"));
    let active_env = tmp.path().join("active");
    let env = [("VIRTUAL_ENV", s(&active_env)), ("PATH", s(&empty_path))];

    // $VIRTUAL_ENV comes before the .venv next to the job; the default sample of a job with
    // fewer than 20 ok items is all of them.
    let out = sparc3d_env(&["validate", s(&job)], &env);
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    let n = example_count();
    assert!(
        err.contains(&format!("validating {n} of {n} ok items")) && err.contains(s(&active)),
        "{err}"
    );

    // None imports pymeshlab: all are named, in the documented order, and the exit code is 2.
    std::fs::write(&active, "#!/bin/sh\nexit 1\n").unwrap_or_else(|e| panic!("{e}"));
    let out = sparc3d_env(&["validate", s(&job)], &env);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    let at = |needle: &str| {
        err.find(needle)
            .unwrap_or_else(|| panic!("{needle} not named: {err}"))
    };
    assert!(
        at(s(&active)) < at(s(&broken)) && at(s(&broken)) < at("python3"),
        "{err}"
    );

    // $SPARC3D_PYTHON alone, when set.
    let chosen = fake_python(&tmp.path().join("chosen"));
    let out = sparc3d_env(
        &["validate", s(&job), "--sample", "2"],
        &[("SPARC3D_PYTHON", s(&chosen)), env[0], env[1]],
    );
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains(&format!("validating 2 of {n}")) && err.contains(s(&chosen)),
        "{err}"
    );

    // --help says so.
    let help = ok(&["validate", "--help"]);
    for needle in [
        "SPARC3D_PYTHON",
        "VIRTUAL_ENV",
        ".venv",
        "python3",
        "at least 20",
    ] {
        assert!(help.contains(needle), "{needle}: {help}");
    }
}

#[test]
fn run_help_shows_the_defaults() {
    let help = ok(&["run", "-h"]);
    for (flag, default) in [
        ("--item-timeout", "10m00s"),
        ("--item-memory", "8G"),
        ("--resolution", "512"),
        ("--shard-size", "256"),
    ] {
        // The flag's line and the lines of its help under it (clap wraps long help).
        let mut lines = help.lines().skip_while(|l| !l.contains(flag));
        let first = lines
            .next()
            .unwrap_or_else(|| panic!("{flag} missing: {help}"));
        let rest: Vec<&str> = lines
            .take_while(|l| !l.trim_start().starts_with('-'))
            .collect();
        let line = format!("{first} {}", rest.join(" "));
        assert!(
            line.contains("[default: ") && line.contains(default),
            "{flag}: {line}"
        );
    }
}

/// The inside test is on by default (its counts and its `inside` stage in the JSON);
/// `--no-inside-test` switches it off (no stage ran), `--inside-test` is the default spelled
/// out, and the two together are refused.
/// `convert MESH -o OUT --resolution N --json` with `extra` flags: its summary.
fn convert_json(mesh: &Path, out: &Path, resolution: &str, extra: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "convert",
        s(mesh),
        "-o",
        s(out),
        "--resolution",
        resolution,
        "--json",
    ];
    args.extend_from_slice(extra);
    serde_json::from_str(&ok(&args)).unwrap_or_else(|e| panic!("{e}"))
}

/// A sphere with a 6-voxel hole at 128³: the exact flood enters it, the sealing keeps it
/// solid (one sealed region, no thin shell); `--no-seal-openings` gives the shell back, and
/// `--no-inside-test` switches the sealing off too (it asks the test's winding number).
#[test]
fn convert_seals_a_holed_sphere_unless_told_not_to() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let unit = 2.0 / 122.0;
    let mesh = tmp.path().join("holed.obj");
    let sphere = sparcubes::shapes::sphere_with_hole([0.0; 3], 1.0, 6.0 * unit, 48);
    sparcubes::io::save(&sphere, &mesh).unwrap_or_else(|e| panic!("{e}"));
    let run = |extra: &[&str]| convert_json(&mesh, &tmp.path().join("o.ply"), "128", extra);
    let on = run(&[]);
    assert_eq!(on["seal_openings"], true, "{on}");
    assert_eq!(on["sealed_pockets"], 1, "{on}");
    assert_eq!(on["shell_vertices"], 0, "{on}");
    assert!(on["stage_seconds"].get("seal").is_some(), "{on}");
    let off = run(&["--no-seal-openings"]);
    assert_eq!(off["seal_openings"], false, "{off}");
    assert_eq!(off["sealed_pockets"], 0, "{off}");
    assert!(off["shell_vertices"].as_u64().unwrap_or(0) > 1000, "{off}");
    let no_test = run(&["--no-inside-test"]);
    assert_eq!(no_test["seal_openings"], false, "{no_test}");
    for v in [&on, &off, &no_test] {
        assert_eq!(
            (v["watertight"].clone(), v["manifold"].clone()),
            (true.into(), true.into())
        );
    }
}

#[test]
fn convert_inside_test_is_on_by_default() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let mesh = examples().join("wuson.stl");
    let run = |extra: &[&str]| convert_json(&mesh, &tmp.path().join("o.ply"), "64", extra);
    let off = run(&["--no-inside-test"]);
    assert_eq!(off["inside_test"], false);
    assert!(off["stage_seconds"].get("inside").is_none(), "{off}");
    assert_eq!(off["enclosed_regions"], 0);
    let on = run(&[]);
    assert_eq!(on["inside_test"], true);
    let spelled = run(&["--inside-test"]);
    assert_eq!(spelled["enclosed_regions"], on["enclosed_regions"]);
    assert_eq!(spelled["output_faces"], on["output_faces"]);
    assert!(on["stage_seconds"].get("inside").is_some(), "{on}");
    // wuson's 51 closed parts overlap: the flood leaves regions enclosed, which the test counts.
    assert!(on["enclosed_regions"].as_u64().unwrap_or(0) > 0, "{on}");
    for v in [&off, &on] {
        assert_eq!(
            (v["watertight"].clone(), v["manifold"].clone()),
            (true.into(), true.into())
        );
    }
    let out = tmp.path().join("o.ply");
    let both = sparc3d(&[
        "convert",
        s(&mesh),
        "-o",
        s(&out),
        "--inside-test",
        "--no-inside-test",
    ]);
    assert!(!both.status.success());
    assert!(
        stderr(&both).contains("cannot be used with"),
        "{}",
        stderr(&both)
    );
}

/// `preview` draws a mesh converted with the inside test unless `--no-inside-test`; a job's
/// item is drawn as the job made it, so either flag is refused with `--id`.
#[test]
fn preview_inside_test_converts_a_mesh_with_it() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let mesh = examples().join("wuson.stl");
    let png = tmp.path().join("p.png");
    let args = |extra: &[&'static str]| -> Vec<String> {
        let mut a: Vec<String> = ["preview", s(&mesh), "-o", s(&png), "--views", "1"]
            .iter()
            .map(|x| x.to_string())
            .collect();
        a.extend(["--tile", "64", "--resolution", "64"].map(String::from));
        a.extend(extra.iter().map(|x| x.to_string()));
        a
    };
    let run = |extra: &[&'static str]| {
        let a = args(extra);
        sparc3d(&a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    for flag in ["--inside-test", "--no-inside-test"] {
        let out = run(&[flag]);
        assert!(out.status.success(), "{}", stderr(&out));
        let png_bytes = std::fs::read(&png).unwrap_or_else(|e| panic!("{e}"));
        assert!(png_bytes.starts_with(b"\x89PNG"), "not a PNG");
        let out = run(&["--id", "x", flag]);
        assert!(!out.status.success());
        assert!(
            stderr(&out).contains("--no-inside-test"),
            "{}",
            stderr(&out)
        );
    }
}

/// `preview --refine` draws the refined output (a before/after pair is two calls): the
/// pictures of one mesh with and without it differ; out-of-range settings are refused naming
/// the setting, and `--refine` is refused for a job's item, drawn as its job made it.
#[test]
fn preview_refine_draws_the_refined_output() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let mesh = examples().join("wuson.stl");
    let draw = |name: &str, extra: &[&str]| {
        let png = tmp.path().join(name);
        let mut a = vec!["preview", s(&mesh), "-o", s(&png), "--views", "1"];
        a.extend(["--tile", "96", "--resolution", "32"]);
        a.extend(extra);
        let out = sparc3d(&a);
        (out, png)
    };
    let (off, off_png) = draw("off.png", &[]);
    assert!(off.status.success(), "{}", stderr(&off));
    let (on, on_png) = draw("on.png", &["--refine"]);
    assert!(on.status.success(), "{}", stderr(&on));
    let read = |p: &std::path::Path| std::fs::read(p).unwrap_or_else(|e| panic!("{e}"));
    assert_ne!(
        read(&off_png),
        read(&on_png),
        "the refined output draws the same"
    );
    let (bad, _) = draw("bad.png", &["--refine", "--refine-views", "0"]);
    assert!(!bad.status.success());
    assert!(stderr(&bad).contains("views"), "{}", stderr(&bad));
    let (item, _) = draw("item.png", &["--id", "x", "--refine"]);
    assert!(!item.status.success());
    assert!(stderr(&item).contains("--refine"), "{}", stderr(&item));
}
