//! End to end, issue 32 ("Reliability, round three"), items 1, 7 and 8: what a job's sources
//! can do to it. A source changed after `init` is a `source_changed` row, never an ok row under
//! its old id; the path column is chosen by one rule that `init` states; `run` fails when no
//! item converted; missing files are all named; a 2 GB STL with an empty header fails fast;
//! `ls` and `failures` escape odd names; `run` at `ulimit -n 12` names the limit.

mod common;

use common::*;
use sparc3d_schema::{ItemStatus, ShardRow};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn write(path: &Path, text: &[u8]) {
    std::fs::write(path, text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

/// Copies bundled examples into `dir/meshes`; returns the folder.
fn meshes(dir: &Path, names: &[&str]) -> PathBuf {
    let root = dir.join("meshes");
    std::fs::create_dir_all(&root).unwrap_or_else(|e| panic!("{e}"));
    for n in names {
        std::fs::copy(example(n), root.join(n)).unwrap_or_else(|e| panic!("{n}: {e}"));
    }
    root
}

fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::{Digest, Sha256};
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Every row of every finished shard, tensors included.
fn rows(job: &Path) -> Vec<ShardRow> {
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
    let mut files: Vec<PathBuf> = std::fs::read_dir(job.join("shards"))
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    files.sort();
    let mut out = Vec::new();
    for p in files
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "parquet"))
    {
        let f = std::fs::File::open(p).unwrap_or_else(|e| panic!("{e}"));
        let reader = ParquetRecordBatchReaderBuilder::try_new(f)
            .and_then(|b| b.build())
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        for batch in reader {
            let batch = batch.unwrap_or_else(|e| panic!("{e}"));
            out.extend(
                sparc3d_schema::columns::arrow::batch_to_rows(&batch)
                    .unwrap_or_else(|e| panic!("{e}")),
            );
        }
    }
    out.sort_by_key(|r| r.item_index);
    out
}

fn init(job: &Path, manifest: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "init",
        s(job),
        "--manifest",
        s(manifest),
        "--resolution",
        "32",
        "--shard-size",
        "1",
    ];
    args.extend_from_slice(extra);
    sparc3d(&args)
}

/// Item 1: a source overwritten with another mesh between `init` and `run` is a failed row
/// of class `source_changed` (named by `failures`, `status` and `ls`), never an ok row with
/// the other mesh's tensors under the old id; every ok row's `source_sha256` is the hash of
/// the bytes converted. Restored and retried by class, it converts.
#[test]
fn a_source_changed_after_init_is_a_source_changed_row_never_an_ok_one() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let dir = meshes(tmp.path(), &["cube.off", "sphere.obj", "wuson.stl"]);
    let manifest = tmp.path().join("m.csv");
    ok(&["manifest", "build", s(&dir), "-o", s(&manifest)]);
    let job = tmp.path().join("job");
    let out = init(&job, &manifest, &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    let cube = dir.join("cube.off");
    let cube_id = sha256_hex(&std::fs::read(&cube).unwrap_or_default());
    // Another mesh in the same format, which would convert: a tetrahedron.
    let tetra: &[u8] =
        b"OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
    write(&cube, tetra);

    let out = sparc3d(&["run", s(&job), "--workers", "2"]);
    assert!(out.status.success(), "2 of 3 converted: {}", stderr(&out));
    let all = rows(&job);
    assert_eq!(all.len(), 3);
    let row = all.iter().find(|r| r.id == cube_id).expect("cube's row");
    assert_eq!(
        row.status,
        ItemStatus::Failed,
        "the changed source converted"
    );
    assert_eq!(row.error_class.map(|c| c.as_str()), Some("source_changed"));
    assert!(row.tensors.is_none());
    assert_eq!(row.source_sha256.as_deref(), Some(&*sha256_hex(tetra)));
    let message = row.error_message.clone().unwrap_or_default();
    assert!(
        message.contains(&cube_id) && message.contains("changed"),
        "{message}"
    );
    for r in all.iter().filter(|r| r.status == ItemStatus::Ok) {
        let bytes = std::fs::read(&r.uri).unwrap_or_default();
        assert_eq!(r.source_sha256.as_deref(), Some(&*sha256_hex(&bytes)));
        assert_eq!(r.source_sha256.as_deref(), Some(&*r.id));
    }

    let failures = ok(&["failures", s(&job)]);
    assert!(
        failures.starts_with(&format!("source_changed\t{cube_id}\t")),
        "{failures}"
    );
    assert_eq!(status(&job)["error_classes"]["source_changed"], 1);
    let ls = ok(&["ls", s(&job)]);
    assert!(
        ls.contains(&format!("{cube_id}\tfailed:source_changed\t")),
        "{ls}"
    );

    // Still changed: retried, it fails the same way; restored, it converts.
    ok(&["retry", s(&job), "--class", "source_changed"]);
    ok(&["run", s(&job), "--workers", "1"]);
    assert_eq!(status(&job)["error_classes"]["source_changed"], 1);
    std::fs::copy(example("cube.off"), &cube).unwrap_or_else(|e| panic!("{e}"));
    ok(&["retry", s(&job), "--class", "source_changed"]);
    ok(&["run", s(&job), "--workers", "1"]);
    let row = rows(&job)
        .into_iter()
        .find(|r| r.id == cube_id)
        .expect("row");
    assert_eq!(row.status, ItemStatus::Ok);
    assert_eq!(row.source_sha256.as_deref(), Some(&*cube_id));
    assert_each_item_once(&job);
}

/// Item 1: with ids and no sha256 column nothing was frozen to compare with; `init` says so,
/// and the row records the hash of the bytes converted (not a hash of the file read apart).
/// A sha256 that is not 64 hex digits is refused at `init`, naming the row.
#[test]
fn without_a_frozen_sha256_the_row_records_what_was_converted() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let dir = meshes(tmp.path(), &["sphere.obj"]);
    let mesh = dir.join("sphere.obj");
    let manifest = tmp.path().join("m.csv");
    write(
        &manifest,
        format!("id,path\nmesh,{}\n", mesh.display()).as_bytes(),
    );
    let job = tmp.path().join("job");
    let out = init(&job, &manifest, &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("1 items have an id but no sha256"),
        "{}",
        stderr(&out)
    );
    // A tetrahedron in place of the sphere.
    write(
        &mesh,
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    );
    ok(&["run", s(&job), "--workers", "1"]);
    let row = rows(&job).pop().expect("a row");
    assert_eq!(row.status, ItemStatus::Ok);
    assert_eq!(row.counts.as_ref().map(|c| c.input_faces), Some(4));
    let converted = sha256_hex(&std::fs::read(&mesh).unwrap_or_default());
    assert_eq!(row.source_sha256.as_deref(), Some(&*converted));

    let bad = tmp.path().join("bad.csv");
    write(
        &bad,
        format!("id,path,sha256\nmesh,{},abc123\n", mesh.display()).as_bytes(),
    );
    let out = init(&tmp.path().join("job2"), &bad, &[]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("row 1: \"abc123\"") && stderr(&out).contains("64 hex digits"),
        "{}",
        stderr(&out)
    );
}

/// Item 7: a manifest with `uri` (URLs) and `local_path` (local copies) converts the local
/// copies and `init` says which column it used; a row with no local path is refused, naming
/// it; two columns of local paths are refused until `--path-column` says which.
#[test]
fn the_path_column_is_chosen_by_one_rule_that_init_states() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let dir = meshes(tmp.path(), &["cube.off", "sphere.obj"]);
    let (cube, sphere) = (dir.join("cube.off"), dir.join("sphere.obj"));
    let manifest = tmp.path().join("both.csv");
    write(
        &manifest,
        format!(
            "id,uri,local_path\na,https://example.com/cube.off,{}\nb,s3://bucket/sphere.obj,{}\n",
            cube.display(),
            sphere.display()
        )
        .as_bytes(),
    );
    let job = tmp.path().join("job");
    let out = init(&job, &manifest, &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("paths from column local_path (uri holds only URLs"),
        "{}",
        stderr(&out)
    );
    // The local paths are the items' sources; the URLs are kept as provenance only.
    let frozen = frozen_text(&job);
    for line in frozen.lines() {
        let item: serde_json::Value = serde_json::from_str(line).unwrap_or_default();
        let source = item["uri"].as_str().unwrap_or_default();
        assert!(
            !source.contains("://"),
            "a URL frozen as the source: {line}"
        );
        assert!(
            item["extra"]["uri"]
                .as_str()
                .is_some_and(|u| u.contains("://")),
            "{line}"
        );
    }
    ok(&["run", s(&job), "--workers", "1"]);
    assert_eq!(status(&job)["ok"], 2);

    let ambiguous = tmp.path().join("ambiguous.csv");
    write(
        &ambiguous,
        format!(
            "id,uri,local_path\na,https://example.com/cube.off,{}\nb,s3://bucket/sphere.obj,\n",
            cube.display()
        )
        .as_bytes(),
    );
    let out = init(&tmp.path().join("job2"), &ambiguous, &[]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("row 2: no local_path, only a URL in uri"),
        "{}",
        stderr(&out)
    );
    assert!(!tmp.path().join("job2/job.json").exists());

    let two = tmp.path().join("two.csv");
    write(
        &two,
        format!("path,local_path\n{},{}\n", cube.display(), sphere.display()).as_bytes(),
    );
    let out = init(&tmp.path().join("job3"), &two, &[]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("several path columns hold local paths (path, local_path)")
            && stderr(&out).contains("--path-column"),
        "{}",
        stderr(&out)
    );
    let job3 = tmp.path().join("job3");
    let out = init(&job3, &two, &["--path-column", "local_path"]);
    assert!(out.status.success(), "{}", stderr(&out));
    // The chosen column is the source; the other is kept as a provenance column.
    let frozen = frozen_text(&job3);
    let item: serde_json::Value = serde_json::from_str(frozen.trim()).unwrap_or_default();
    assert!(
        item["uri"]
            .as_str()
            .is_some_and(|u| u.ends_with("sphere.obj"))
            && item["extra"]["path"]
                .as_str()
                .is_some_and(|p| p.ends_with("cube.off")),
        "{frozen}"
    );
}

/// Item 7: `run` exits non-zero when every item failed (here every file is gone, as when a
/// manifest names another machine's paths), saying so; one good item is enough for 0.
#[test]
fn run_fails_when_no_item_converted() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let manifest = tmp.path().join("gone.csv");
    write(
        &manifest,
        b"id,path\na,/nonexistent/sparc3d/a.obj\nb,/nonexistent/sparc3d/b.obj\n",
    );
    let job = tmp.path().join("job");
    let out = init(&job, &manifest, &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    let out = sparc3d(&["run", s(&job), "--workers", "1"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("no item converted: all 2 items failed (2 io_error)"),
        "{}",
        stderr(&out)
    );
    assert_eq!(status(&job)["pending"], 0);

    let mixed = tmp.path().join("mixed.csv");
    write(
        &mixed,
        format!(
            "id,path\na,/nonexistent/sparc3d/a.obj\nb,{}\n",
            example("cube.off").display()
        )
        .as_bytes(),
    );
    let job2 = tmp.path().join("job2");
    assert!(init(&job2, &mixed, &[]).status.success());
    ok(&["run", s(&job2), "--workers", "1"]);
}

/// Item 8: a path-only manifest with 25 missing files names the first ten by row and path,
/// and how many more, instead of the first alone.
#[test]
fn a_path_only_manifest_with_missing_files_names_them() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let mut text = String::from("path\n");
    for i in 0..25 {
        text.push_str(&format!("/nonexistent/sparc3d/m{i:02}.obj\n"));
    }
    text.push_str(&format!("{}\n", example("cube.off").display()));
    let manifest = tmp.path().join("m.csv");
    write(&manifest, text.as_bytes());
    let out = init(&tmp.path().join("job"), &manifest, &[]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(err.contains("25 of 26 files could not be hashed"), "{err}");
    for i in 0..10 {
        assert!(
            err.contains(&format!(
                "row {}: opening /nonexistent/sparc3d/m{i:02}.obj",
                i + 1
            )),
            "row {}: {err}",
            i + 1
        );
    }
    assert!(err.contains("and 15 more"), "{err}");
}

/// Peak resident memory (KiB) of a command run to its end, from `wait4` (which reaps the
/// child: std's `wait` cannot hand back its resource usage).
#[allow(clippy::zombie_processes)]
fn peak_rss_kib(args: &[&str]) -> (Output, i64) {
    use std::os::unix::process::ExitStatusExt;
    let child = Command::new(bin())
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("{e}"));
    let pid = child.id() as libc::pid_t;
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let (mut so, mut se) = (child.stdout, child.stderr);
    let t = std::thread::spawn(move || {
        use std::io::Read;
        if let Some(e) = se.as_mut() {
            let _ = e.read_to_end(&mut err);
        }
        err
    });
    if let Some(o) = so.as_mut() {
        use std::io::Read;
        let _ = o.read_to_end(&mut out);
    }
    let err = t.join().unwrap_or_default();
    let mut status = 0;
    // SAFETY: a zeroed rusage is a valid value; wait4 fills it and the status for our child.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let waited = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    assert_eq!(waited, pid, "wait4");
    let output = Output {
        status: std::process::ExitStatus::from_raw(status),
        stdout: out,
        stderr: err,
    };
    (output, usage.ru_maxrss)
}

/// Item 8: a 2 GB sparse all-zero `.stl` (its header claims 0 triangles) is an empty mesh from
/// its header: `convert` says "empty mesh" without reading the file (its peak memory stays far
/// below the file's size), and in a job it is an `empty_mesh` row.
#[test]
fn a_2_gb_stl_whose_header_claims_no_triangle_fails_fast() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let stl = tmp.path().join("zeros.stl");
    let f = std::fs::File::create(&stl).unwrap_or_else(|e| panic!("{e}"));
    f.set_len(2 << 30)
        .unwrap_or_else(|e| panic!("a sparse 2 GiB file: {e}"));
    drop(f);
    let ply = tmp.path().join("out.ply");
    let (out, peak_kib) = peak_rss_kib(&["convert", s(&stl), "-o", s(&ply)]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("empty mesh") && err.contains("claims 0 triangles"),
        "{err}"
    );
    assert!(
        peak_kib < 256 << 10,
        "peak RSS {peak_kib} KiB: the file was read ({err})"
    );

    let manifest = tmp.path().join("m.csv");
    write(
        &manifest,
        format!("id,path\nzeros,{}\n", stl.display()).as_bytes(),
    );
    let job = tmp.path().join("job");
    assert!(init(&job, &manifest, &[]).status.success());
    let _ = sparc3d(&["run", s(&job), "--workers", "1"]);
    let failures = ok(&["failures", s(&job)]);
    assert!(
        failures.starts_with("empty_mesh\tzeros\t") && failures.contains("claims 0 triangles"),
        "{failures}"
    );
}

/// Undoes `ls`/`failures` escaping (`\\`, `\t`, `\n`, `\r`, `\xNN`).
fn unescape(field: &str) -> String {
    let mut out = String::new();
    let mut chars = field.chars();
    while let Some(c) = chars.next() {
        if c != '\\' {
            out.push(c);
            continue;
        }
        match chars.next() {
            Some('t') => out.push('\t'),
            Some('n') => out.push('\n'),
            Some('r') => out.push('\r'),
            Some('\\') => out.push('\\'),
            Some('x') => {
                let hex: String = chars.by_ref().take(2).collect();
                out.push(u8::from_str_radix(&hex, 16).map_or('?', char::from));
            }
            other => panic!("bad escape \\{other:?} in {field:?}"),
        }
    }
    out
}

/// Item 8: names with a tab, a newline and a backslash keep `ls` and `failures` one line per
/// item with the same fields; unescaped, the fields are the paths.
#[test]
fn ls_and_failures_escape_tabs_and_newlines_in_names() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let dir = tmp.path().join("odd");
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{e}"));
    let good = dir.join("tab\there\\cube.off");
    std::fs::copy(example("cube.off"), &good).unwrap_or_else(|e| panic!("{e}"));
    let bad = dir.join("new\nline.obj");
    write(&bad, b"this is not a mesh\n");
    let manifest = tmp.path().join("m.csv");
    ok(&["manifest", "build", s(&dir), "-o", s(&manifest)]);
    let job = tmp.path().join("job");
    assert!(init(&job, &manifest, &[]).status.success());
    let _ = sparc3d(&["run", s(&job), "--workers", "1"]);

    let ls = ok(&["ls", s(&job)]);
    let lines: Vec<&str> = ls.lines().collect();
    assert_eq!(lines.len(), 2, "{ls:?}");
    let mut uris: Vec<String> = lines
        .iter()
        .map(|l| {
            let fields: Vec<&str> = l.split('\t').collect();
            assert_eq!(fields.len(), 3, "{l:?}");
            unescape(fields[2])
        })
        .collect();
    uris.sort();
    let mut want = vec![s(&bad).to_string(), s(&good).to_string()];
    want.sort();
    assert_eq!(uris, want);

    let failures = ok(&["failures", s(&job)]);
    let lines: Vec<&str> = failures.lines().collect();
    assert_eq!(lines.len(), 1, "{failures:?}");
    let fields: Vec<&str> = lines[0].split('\t').collect();
    assert_eq!(fields.len(), 4, "{:?}", lines[0]);
    assert_eq!(fields[0], "parse_error");
    assert_eq!(unescape(fields[2]), s(&bad));
    assert!(unescape(fields[3]).contains(s(&bad)), "{:?}", fields[3]);
}

/// Item 8: `run` at `ulimit -n 12` fails naming the limit and the shards left (as
/// docs/RELIABILITY.md says of any failure), and a run with the usual limit finishes the job.
#[test]
fn run_out_of_file_descriptors_names_the_limit_and_the_shards_left() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let dir = meshes(
        tmp.path(),
        &[
            "cube.off",
            "sphere.obj",
            "wuson.stl",
            "cube_binary.ply",
            "box_textured.glb",
        ],
    );
    let manifest = tmp.path().join("m.csv");
    ok(&["manifest", "build", s(&dir), "-o", s(&manifest)]);
    let job = tmp.path().join("job");
    assert!(init(&job, &manifest, &[]).status.success());
    let out = Command::new("sh")
        .arg("-c")
        .arg("ulimit -n 12 && exec \"$0\" run \"$1\" --workers 3")
        .arg(bin())
        .arg(&job)
        .output()
        .unwrap_or_else(|e| panic!("{e}"));
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("open-file limit is 12"), "{err}");
    let left = err
        .split("are not finished (shards ")
        .nth(1)
        .unwrap_or_else(|| panic!("no shards named: {err}"));
    assert!(left.starts_with(|c: char| c.is_ascii_digit()), "{err}");
    let out = sparc3d(&["run", s(&job), "--workers", "2"]);
    assert!(out.status.success(), "{}{}", stdout(&out), stderr(&out));
    assert_each_item_once(&job);
    assert_eq!(status(&job)["ok"], 5);
}
