//! Helpers of the end-to-end tests: a corpus of real and broken meshes, running the binary,
//! reading shards back.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A bundled example mesh (`examples/NAME`).
pub fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../examples")
        .join(name)
}

/// The built `sparc3d` binary.
pub fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_sparc3d"))
}

/// Runs the binary with arguments; returns its output.
pub fn sparc3d(args: &[&str]) -> Output {
    sparc3d_env(args, &[])
}

/// Runs the binary with arguments and extra environment variables, without the cluster task
/// index variables of the calling shell; returns its output.
pub fn sparc3d_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(bin());
    c.args(args)
        .env_remove("SLURM_ARRAY_TASK_ID")
        .env_remove("JOB_COMPLETION_INDEX");
    for (k, v) in env {
        c.env(k, v);
    }
    c.output()
        .unwrap_or_else(|e| panic!("running sparc3d {args:?}: {e}"))
}

/// Runs the binary and panics with its stderr when it fails.
pub fn ok(args: &[&str]) -> String {
    ok_env(args, &[])
}

/// [`ok`] with extra environment variables.
pub fn ok_env(args: &[&str], env: &[(&str, &str)]) -> String {
    let out = sparc3d_env(args, env);
    assert!(
        out.status.success(),
        "sparc3d {args:?} failed: {}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Writes the mesh (vertices `v`, triangles `f`) as an OBJ file at `path`.
pub fn write_obj(path: &Path, v: &[[f64; 3]], f: &[[usize; 3]]) {
    let mut s = String::new();
    for p in v {
        s.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
    }
    for t in f {
        s.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    std::fs::write(path, s).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

/// A box of size `d` at corner `o`: its eight corners (corner i at bit 0, 1, 2 of i along x,
/// y, z) and twelve outward triangles.
pub fn boxed(d: [f64; 3], o: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let mut v = Vec::new();
    for i in 0..8 {
        v.push([
            o[0] + d[0] * (i & 1) as f64,
            o[1] + d[1] * ((i >> 1) & 1) as f64,
            o[2] + d[2] * ((i >> 2) & 1) as f64,
        ]);
    }
    let f = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    (v, f)
}

/// A UV sphere of radius `r` with `n` rings and `2n` segments: `4n(n - 1)` triangles.
pub fn sphere(n: usize, r: f64) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let mut v = vec![[0.0, 0.0, r], [0.0, 0.0, -r]];
    let rings = n;
    let segs = 2 * n;
    for i in 1..rings {
        let th = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segs {
            let ph = 2.0 * std::f64::consts::PI * j as f64 / segs as f64;
            v.push([
                r * th.sin() * ph.cos(),
                r * th.sin() * ph.sin(),
                r * th.cos(),
            ]);
        }
    }
    let at = |i: usize, j: usize| 2 + (i - 1) * segs + j % segs;
    let mut f = Vec::new();
    for j in 0..segs {
        f.push([0, at(1, j), at(1, j + 1)]);
        f.push([1, at(rings - 1, j + 1), at(rings - 1, j)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segs {
            f.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            f.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    (v, f)
}

/// Names of the broken files in the corpus and the classes they must fail with.
pub const BROKEN: [(&str, &str); 4] = [
    ("broken_garbage.obj", "parse_error"),
    ("broken_truncated.ply", "parse_error"),
    ("broken_empty.stl", "parse_error"),
    ("broken_no_faces.obj", ""),
];

/// Writes a corpus of 30+ meshes: the bundled examples, generated closed and open shapes,
/// and broken files. Returns the folder.
pub fn corpus(dir: &Path) -> PathBuf {
    let root = dir.join("meshes");
    std::fs::create_dir_all(&root).unwrap_or_else(|e| panic!("{e}"));
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    if let Ok(entries) = std::fs::read_dir(&examples) {
        for e in entries.flatten() {
            let p = e.path();
            if sparcubes::io::Format::from_extension(&p).is_some() {
                let _ = std::fs::copy(&p, root.join(e.file_name()));
            }
        }
    }
    for i in 0..12 {
        let k = i as f64;
        let (v, f) = boxed(
            [1.0 + k * 0.3, 1.0 + (k * 0.7) % 2.0, 0.5 + k * 0.1],
            [k, -k, 0.5 * k],
        );
        write_obj(&root.join(format!("box_{i:02}.obj")), &v, &f);
    }
    for i in 0..8 {
        let (v, f) = sphere(4 + 2 * i, 1.0 + i as f64 * 0.25);
        write_obj(&root.join(format!("sphere_{i:02}.obj")), &v, &f);
    }
    for i in 0..4 {
        // Open sheets (one quad, tilted) and a box missing a face.
        let t = 0.2 * i as f64;
        write_obj(
            &root.join(format!("sheet_{i:02}.obj")),
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, t],
                [1.0, 1.0, 2.0 * t],
                [0.0, 1.0, t],
            ],
            &[[0, 1, 2], [0, 2, 3]],
        );
    }
    let (v, mut f) = boxed([1.0, 2.0, 3.0], [0.0; 3]);
    f.truncate(10);
    write_obj(&root.join("open_box.obj"), &v, &f);
    std::fs::write(
        root.join("broken_garbage.obj"),
        "this is not a mesh\n\u{1}\u{2}",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(
        root.join("broken_truncated.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3\n",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(root.join("broken_empty.stl"), "").unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(
        root.join("broken_no_faces.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\n",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    root
}

/// Every row of every finished shard of a job: (item_index, id, status, error_class).
pub fn all_rows(job: &Path) -> Vec<(u64, String, String, Option<String>)> {
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
    let mut out = Vec::new();
    let mut files: Vec<_> = std::fs::read_dir(job.join("shards"))
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_else(|_| Vec::new());
    files.sort();
    for p in files {
        if p.extension().and_then(|e| e.to_str()) != Some("parquet") {
            continue;
        }
        let f = std::fs::File::open(&p).unwrap_or_else(|e| panic!("{e}"));
        let reader = ParquetRecordBatchReaderBuilder::try_new(f)
            .and_then(|b| b.build())
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        for batch in reader {
            let batch = batch.unwrap_or_else(|e| panic!("{e}"));
            for r in sparc3d_schema::columns::arrow::batch_to_rows(&batch)
                .unwrap_or_else(|e| panic!("{e}"))
            {
                out.push((
                    r.item_index,
                    r.id,
                    r.status.as_str().to_string(),
                    r.error_class.map(|c| c.as_str().to_string()),
                ));
            }
        }
    }
    out
}

/// `inspect --json` of a job.
pub fn inspect(job: &Path) -> serde_json::Value {
    let text = ok(&["inspect", &job.to_string_lossy(), "--json"]);
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}: {text}"))
}

/// `status --json` of a job.
pub fn status(job: &Path) -> serde_json::Value {
    let text = ok(&["status", &job.to_string_lossy(), "--json"]);
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}: {text}"))
}

/// The slice files of a job's frozen manifest (`manifest/part-NNNNN.<sha>.jsonl`), in shard
/// order.
#[allow(dead_code)]
pub fn slice_files(job: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(job.join("manifest"))
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    files.retain(|p| {
        let name = p
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        name.starts_with("part-") && name.ends_with(".jsonl")
    });
    files.sort();
    files
}

/// The frozen manifest's lines, every slice in shard order (as `manifest.jsonl` held them
/// before slices); only the slices `job.json` pins, so an orphan left by a stopped `add` is
/// not read.
#[allow(dead_code)]
pub fn frozen_text(job: &Path) -> String {
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(job.join("job.json")).unwrap_or_default())
            .unwrap_or_default();
    let shards = file["shards"].as_u64().unwrap_or(0);
    let mut text = String::new();
    for shard in 0..shards {
        let prefix = format!("part-{shard:05}.");
        let pinned: Vec<PathBuf> = slice_files(job)
            .into_iter()
            .filter(|p| {
                p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with(&prefix))
            })
            .collect();
        // Of several files of one shard (an orphan), the one whose sha256 a page lists.
        let pages = page_text(job);
        for p in pinned {
            let bytes = std::fs::read(&p).unwrap_or_default();
            let sha = sparc3d_schema::hex::sha256_hex(&bytes);
            if pages.contains(&sha) {
                text.push_str(&String::from_utf8_lossy(&bytes));
            }
        }
    }
    text
}

/// Every index page's text, concatenated (for [`frozen_text`]).
fn page_text(job: &Path) -> String {
    let mut files: Vec<PathBuf> = std::fs::read_dir(job.join("manifest"))
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    files.retain(|p| p.extension().is_some_and(|e| e == "tsv"));
    files
        .iter()
        .map(|p| std::fs::read_to_string(p).unwrap_or_default())
        .collect()
}

/// Item ids of a frozen manifest.
pub fn manifest_ids(job: &Path) -> Vec<String> {
    let text = frozen_text(job);
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}"));
            v["id"].as_str().unwrap_or_default().to_string()
        })
        .collect()
}

/// Checks that every manifest item appears exactly once in the shards.
pub fn assert_each_item_once(job: &Path) {
    let ids = manifest_ids(job);
    let rows = all_rows(job);
    assert_eq!(rows.len(), ids.len(), "rows vs manifest items");
    let mut seen = std::collections::HashSet::new();
    for (index, id, _, _) in &rows {
        assert!(seen.insert(id.clone()), "item {id} appears twice");
        assert_eq!(&ids[*index as usize], id, "item index {index}");
    }
}

/// Pids of every descendant of `pid` (from /proc).
pub fn descendants(pid: u32) -> Vec<u32> {
    let mut parent_of = Vec::new();
    if let Ok(d) = std::fs::read_dir("/proc") {
        for e in d.flatten() {
            let Ok(p) = e.file_name().to_string_lossy().parse::<u32>() else {
                continue;
            };
            let Ok(stat) = std::fs::read_to_string(format!("/proc/{p}/stat")) else {
                continue;
            };
            // "pid (comm) state ppid ..."; comm may hold spaces: split after the last ')'.
            let Some(rest) = stat.rsplit_once(')').map(|x| x.1) else {
                continue;
            };
            let ppid: u32 = rest
                .split_whitespace()
                .nth(1)
                .and_then(|x| x.parse().ok())
                .unwrap_or(0);
            parent_of.push((p, ppid));
        }
    }
    let mut out = Vec::new();
    let mut frontier = vec![pid];
    while let Some(q) = frontier.pop() {
        for &(p, pp) in &parent_of {
            if pp == q && !out.contains(&p) {
                out.push(p);
                frontier.push(p);
            }
        }
    }
    out
}

/// Sends SIGKILL to `pid`; whether it was delivered.
pub fn kill9(pid: u32) -> bool {
    Command::new("kill")
        .args(["-9", &pid.to_string()])
        .status()
        .map(|s| s.success())
        .unwrap_or(false)
}

/// A path as a command-line argument (test paths are UTF-8).
pub fn s(p: &Path) -> &str {
    p.to_str().expect("test paths are UTF-8")
}

/// A manifest of 12 meshes of [`corpus`] in `dir`: the bundled examples, a few boxes and
/// spheres, an open sheet, an open box and one broken file.
pub fn twelve_mesh_manifest(dir: &Path) -> PathBuf {
    let meshes = corpus(dir);
    let full = dir.join("all.csv");
    ok(&["manifest", "build", s(&meshes), "-o", s(&full)]);
    let names = [
        "cube.off",
        "cube_binary.ply",
        "sphere.obj",
        "wuson.stl",
        "box_textured.glb",
        "box_00.obj",
        "box_01.obj",
        "sphere_00.obj",
        "sphere_01.obj",
        "sheet_00.obj",
        "open_box.obj",
        "broken_garbage.obj",
    ];
    let text = std::fs::read_to_string(&full).unwrap_or_else(|e| panic!("{e}"));
    let mut lines = text.lines();
    let header = lines.next().unwrap_or_default().to_string();
    let rows: Vec<&str> = lines
        .filter(|l| names.iter().any(|n| l.contains(&format!("/{n},"))))
        .collect();
    assert_eq!(rows.len(), names.len(), "fixture rows: {rows:?}");
    let manifest = dir.join("m.csv");
    std::fs::write(&manifest, format!("{header}\n{}\n", rows.join("\n")))
        .unwrap_or_else(|e| panic!("{e}"));
    manifest
}

/// The column names of a shard file.
pub fn column_names(path: &Path) -> Vec<String> {
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
    let f = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let b = ParquetRecordBatchReaderBuilder::try_new(f).unwrap_or_else(|e| panic!("{e}"));
    b.schema()
        .fields()
        .iter()
        .map(|f| f.name().clone())
        .collect()
}

/// The shard files of a job, in shard order.
pub fn shard_files(job: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(job.join("shards"))
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    files.retain(|p| p.extension().is_some_and(|e| e == "parquet"));
    files.sort();
    files
}
