//! Validation of a job's output with pymeshlab (docs/VALIDATION.md), the logic behind
//! `sparc3d validate` and `run --validate-sample`: a reproducible sample of a job's `ok` items.
//!
//! Each sampled row is decoded (the same decode as `show`), its mesh extracted in the source
//! frame and written to a temporary PLY next to a PLY of the source as `sparc3d` loads it
//! (node transforms applied). One Python process (`pipeline/validate/validate.py`, built into the
//! binary) checks the whole sample, one JSON line in and one out per item: boundary edges,
//! non-manifold edges and vertices, orientation, volume, components, and the Hausdorff
//! distance both ways. The report goes to `JOB/validation/report.jsonl` and
//! `JOB/validation/summary.md`.

use crate::rows::sample::{self, SampleSize};
use crate::util::stats::median;
use anyhow::{bail, Context, Result};
use serde_json::{json, Value};
use sparc3d_schema::ShardRow;
use sparc3d_workers::Job;
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Lines, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};

/// The validator script, built into the binary so an installed `sparc3d` needs no checkout.
const VALIDATE_PY: &str = include_str!("../../validate/validate.py");

/// The one command that installs what the validator needs.
pub const INSTALL_HINT: &str = "python3 -m pip install -r pipeline/validate/requirements.txt";

/// The smallest default sample (all `ok` items when there are fewer): 1% of a small job is
/// one item, which says little.
pub const DEFAULT_MIN_SAMPLE: usize = 20;

/// How the interpreter is found, for `validate --help` (kept in step with
/// [`python_candidates`]).
pub const PYTHON_HELP: &str = "The checks run in Python with pymeshlab and numpy. The first \
interpreter that imports both is used, tried in this order:
  1. $SPARC3D_PYTHON (when set, the only one tried)
  2. $VIRTUAL_ENV/bin/python (the activated virtual environment)
  3. .venv/bin/python next to the job folder, inside it, and in the current folder
  4. python3 on PATH
Install what it needs with: python3 -m pip install -r pipeline/validate/requirements.txt";

/// What to check and how.
#[derive(Debug, Clone, Copy)]
pub struct Options {
    /// Sample size; `None`: the job's `validation_sample_rate`.
    pub sample: Option<SampleSize>,
    /// Seed of the sample.
    pub seed: u64,
    /// Largest Hausdorff distance in voxels that passes.
    pub max_hausdorff_voxels: f64,
    /// Points sampled per mesh for the Hausdorff distance.
    pub hausdorff_samples: usize,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            sample: None,
            seed: 0,
            max_hausdorff_voxels: 3.0,
            hausdorff_samples: 50_000,
        }
    }
}

/// The result of a validation.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Items with a failed check or an error.
    pub failed: usize,
    /// Summary as JSON (what `--json` prints): counts, checks, paths of the report files.
    pub summary: Value,
}

/// Why validation could not run at all (as opposed to checks failing).
#[derive(Debug)]
pub struct NoPymeshlab(pub String);

impl std::fmt::Display for NoPymeshlab {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for NoPymeshlab {}

/// Interpreters to try, in order ([`PYTHON_HELP`]): `$SPARC3D_PYTHON` alone when set; else
/// `$VIRTUAL_ENV/bin/python`; `.venv/bin/python` next to the job, in the job folder and in
/// the current folder; `python3`.
fn python_candidates(job: &Path) -> Vec<PathBuf> {
    if let Some(p) = std::env::var_os("SPARC3D_PYTHON").filter(|p| !p.is_empty()) {
        return vec![PathBuf::from(p)];
    }
    let python = |venv: &Path| venv.join("bin").join("python");
    let venv = |dir: &Path| python(&dir.join(".venv"));
    let mut c = Vec::new();
    if let Some(active) = std::env::var_os("VIRTUAL_ENV").filter(|p| !p.is_empty()) {
        c.push(python(Path::new(&active)));
    }
    let abs = std::path::absolute(job).unwrap_or_else(|_| job.to_path_buf());
    if let Some(parent) = abs.parent() {
        c.push(venv(parent));
    }
    c.push(venv(&abs));
    if let Ok(cwd) = std::env::current_dir() {
        c.push(venv(&cwd));
    }
    c.retain(|p| p.exists());
    c.dedup();
    c.push(PathBuf::from("python3"));
    c
}

/// The first interpreter that imports pymeshlab, or [`NoPymeshlab`] naming those tried and the
/// install command.
pub fn find_python(job: &Path) -> Result<PathBuf> {
    let candidates = python_candidates(job);
    for c in &candidates {
        let ok = Command::new(c)
            .args(["-c", "import numpy, pymeshlab"])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        if ok {
            return Ok(c.clone());
        }
    }
    let tried: Vec<String> = candidates.iter().map(|c| c.display().to_string()).collect();
    Err(NoPymeshlab(format!(
        "validation needs pymeshlab, which none of these Pythons can import: {}. Install it \
         with `{INSTALL_HINT}` (from the sparc3d checkout, in the active virtual environment, \
         a .venv next to the job or in the current folder), or set SPARC3D_PYTHON to an \
         interpreter that has it (`sparc3d validate --help` gives the order)",
        tried.join(", ")
    ))
    .into())
}

/// One sampled item made ready for the validator: its meshes on disk, or why not.
struct Prepared {
    item_index: u64,
    id: String,
    uri: String,
    resolution: u32,
    output_faces: usize,
    /// Output PLY, source PLY, voxel length in the source frame; or the stage and error.
    files: std::result::Result<(PathBuf, PathBuf, f64), (String, String)>,
}

/// Decodes a row, extracts its mesh in the source frame and writes it and its source to PLYs
/// in `work`.
fn prepare(row: &ShardRow, work: &Path) -> Prepared {
    let mut p = Prepared {
        item_index: row.item_index,
        id: row.id.clone(),
        uri: row.uri.clone(),
        resolution: row.resolution,
        output_faces: 0,
        files: Err((String::new(), String::new())),
    };
    let fail = |stage: &str, e: String| Err((stage.to_string(), e));
    let cubes = match row.cubes() {
        Ok(c) => c,
        Err(e) => {
            p.files = fail("decode", e.to_string());
            return p;
        }
    };
    let mesh = sparcubes::extract::extract_to_source(&cubes);
    p.output_faces = mesh.triangles.len();
    let out = work.join(format!("{}-output.ply", row.item_index));
    if let Err(e) = sparcubes::io::save(&mesh, &out) {
        p.files = fail("write output", format!("{}: {e}", out.display()));
        return p;
    }
    let source = match sparc3d_workers::item::source::load_mesh(&row.uri) {
        Ok(s) => s.mesh,
        Err(e) => {
            p.files = fail("load source", e);
            return p;
        }
    };
    let src = work.join(format!("{}-source.ply", row.item_index));
    if let Err(e) = sparcubes::io::save(&source, &src) {
        p.files = fail("write source", format!("{}: {e}", src.display()));
        return p;
    }
    let voxel = 1.0 / (cubes.normalization.scale * cubes.resolution.max(1) as f64);
    p.files = Ok((out, src, voxel));
    p
}

/// Validates a sample of the job at `job_dir`; writes the report files and returns the outcome.
/// Progress goes to stderr.
pub fn validate_job(job_dir: &Path, options: &Options) -> Result<Outcome> {
    let job = crate::job::setup::open_read_only(job_dir)?;
    let python = find_python(job_dir)?;
    let size = options.sample.unwrap_or(SampleSize::FractionAtLeast(
        job.file.config.validation_sample_rate,
        DEFAULT_MIN_SAMPLE,
    ));
    let drawn = sample::draw(&job, size, options.seed)?;
    let dir = job.layout.root.join("validation");
    let work = dir.join("work");
    std::fs::create_dir_all(&work).with_context(|| format!("creating {}", work.display()))?;
    let script = work.join("validate.py");
    std::fs::write(&script, VALIDATE_PY)
        .with_context(|| format!("writing {}", script.display()))?;
    eprintln!(
        "validating {} of {} ok items of {} (sample {size}, seed {}) with {}",
        drawn.items.len(),
        drawn.population,
        job_dir.display(),
        options.seed,
        python.display()
    );
    let probe = Command::new(&python)
        .arg(&script)
        .arg("--probe")
        .output()
        .with_context(|| format!("running {}", python.display()))?;
    let versions: Value = serde_json::from_slice(&probe.stdout).unwrap_or(Value::Null);
    let mut validator = Validator::start(&python, &script, &work)?;
    let rows = check_sample(&job, &drawn, &work, &mut validator, options)?;
    validator.finish();
    let summary = json!({
        "job": job_dir,
        "population": drawn.population,
        "sample": size.to_string(),
        "seed": options.seed,
        "max_hausdorff_voxels": options.max_hausdorff_voxels,
        "versions": versions,
    });
    let outcome = write_reports(&dir, summary, &rows)?;
    let _ = std::fs::remove_dir_all(&work);
    Ok(outcome)
}

/// The validator process: one JSON line in and one out per item.
struct Validator {
    child: Child,
    stdin: ChildStdin,
    answers: Lines<BufReader<ChildStdout>>,
    stderr_path: PathBuf,
}

impl Validator {
    /// Starts `python script`, its stderr going to a file in `work`.
    fn start(python: &Path, script: &Path, work: &Path) -> Result<Self> {
        let stderr_path = work.join("python.stderr");
        let stderr_file = std::fs::File::create(&stderr_path)
            .with_context(|| format!("creating {}", stderr_path.display()))?;
        let mut child = Command::new(python)
            .arg(script)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(stderr_file)
            .spawn()
            .with_context(|| format!("starting {} {}", python.display(), script.display()))?;
        let (Some(stdin), Some(stdout)) = (child.stdin.take(), child.stdout.take()) else {
            bail!("the validator's pipes could not be opened");
        };
        Ok(Self {
            child,
            stdin,
            answers: BufReader::new(stdout).lines(),
            stderr_path,
        })
    }

    /// The error for a validator that stopped answering, with the end of its stderr.
    fn died(&self, what: &str) -> anyhow::Error {
        let tail = std::fs::read_to_string(&self.stderr_path).unwrap_or_default();
        let tail: String = tail
            .chars()
            .rev()
            .take(2000)
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .collect();
        anyhow::anyhow!("the validator {what}; its stderr ends with:\n{tail}")
    }

    /// The report row of one prepared item: its checks, or why it could not be checked.
    fn check(&mut self, p: &Prepared, options: &Options) -> Result<Value> {
        let mut row = json!({
            "item_index": p.item_index,
            "id": p.id,
            "uri": p.uri,
            "resolution": p.resolution,
            "output_faces": p.output_faces,
        });
        let (out, src, voxel) = match &p.files {
            Err((stage, e)) => {
                row["ok"] = json!(false);
                row["stage"] = json!(stage);
                row["error"] = json!(e);
                row["checks"] = json!({});
                row["measures"] = json!({});
                return Ok(row);
            }
            Ok(files) => files,
        };
        let req = json!({
            "id": p.id,
            "output": out,
            "source": src,
            "voxel": voxel,
            "max_hausdorff_voxels": options.max_hausdorff_voxels,
            "hausdorff_samples": options.hausdorff_samples,
        });
        if writeln!(self.stdin, "{req}")
            .and_then(|_| self.stdin.flush())
            .is_err()
        {
            return Err(self.died("stopped reading"));
        }
        let line = match self.answers.next() {
            Some(Ok(l)) => l,
            _ => return Err(self.died(&format!("ended at item {:?}", p.id))),
        };
        let answer: Value = serde_json::from_str(&line)
            .with_context(|| format!("the validator's answer for item {:?}: {line}", p.id))?;
        for key in ["ok", "checks", "measures", "error"] {
            row[key] = answer.get(key).cloned().unwrap_or(Value::Null);
        }
        if !answer["error"].is_null() {
            row["stage"] = json!("pymeshlab");
        }
        let _ = std::fs::remove_file(out);
        let _ = std::fs::remove_file(src);
        Ok(row)
    }

    /// Closes its input and waits for it.
    fn finish(mut self) {
        drop(self.stdin);
        let _ = self.child.wait();
    }
}

/// Checks every drawn item, decoding and writing the next one while the validator checks
/// the current one; prints failures and progress.
fn check_sample(
    job: &Job,
    drawn: &sample::Sample,
    work: &Path,
    validator: &mut Validator,
    options: &Options,
) -> Result<Vec<Value>> {
    let mut rows: Vec<Value> = Vec::new();
    let total = drawn.items.len();
    std::thread::scope(|scope| -> Result<()> {
        let (tx, rx) = std::sync::mpsc::sync_channel::<Result<Prepared>>(1);
        scope.spawn(move || {
            let res = sample::for_each_sampled_row(job, drawn, |row| {
                tx.send(Ok(prepare(&row, work)))
                    .map_err(|_| anyhow::anyhow!("validation stopped"))
            });
            if let Err(e) = res {
                let _ = tx.send(Err(e));
            }
        });
        for prepared in rx {
            let p = prepared?;
            let row = validator.check(&p, options)?;
            if row["ok"] != json!(true) {
                eprintln!("  FAIL {} ({}): {}", p.id, p.uri, failure_text(&row));
            }
            rows.push(row);
            if rows.len().is_multiple_of(10) || rows.len() == total {
                eprintln!("  {}/{total} checked", rows.len());
            }
        }
        Ok(())
    })?;
    Ok(rows)
}

/// Writes `report.jsonl` and `summary.md` into `dir`; `head` holds the summary's first keys
/// (job, sample, seed, limit, versions), completed here with the counts.
fn write_reports(dir: &Path, head: Value, rows: &[Value]) -> Result<Outcome> {
    let report = dir.join("report.jsonl");
    let mut text = String::new();
    for r in rows {
        text.push_str(&serde_json::to_string(r)?);
        text.push('\n');
    }
    write_atomic(&report, text.as_bytes())?;
    let passed = rows.iter().filter(|r| r["ok"] == json!(true)).count();
    let failed = rows.len() - passed;
    let hausdorff = measure(rows, "hausdorff_voxels");
    let summary = json!({
        "job": head["job"],
        "population": head["population"],
        "sample": head["sample"],
        "seed": head["seed"],
        "checked": rows.len(),
        "passed": passed,
        "failed": failed,
        "checks": check_counts(rows),
        "max_hausdorff_voxels": head["max_hausdorff_voxels"],
        "hausdorff_voxels_median": median(&hausdorff),
        "hausdorff_voxels_max": hausdorff.iter().copied().fold(None, |m: Option<f64>, x| Some(m.map_or(x, |m| m.max(x)))),
        "versions": head["versions"],
        "report": report,
        "summary_md": dir.join("summary.md"),
    });
    let summary_md = dir.join("summary.md");
    write_atomic(&summary_md, markdown(&summary, rows).as_bytes())?;
    eprintln!(
        "{passed} of {} passed, {failed} failed; report: {}",
        rows.len(),
        summary_md.display()
    );
    Ok(Outcome { failed, summary })
}

/// The failed checks of a report row, or its error.
fn failure_text(row: &Value) -> String {
    if let Some(e) = row["error"].as_str() {
        let stage = row["stage"].as_str().unwrap_or("");
        return format!("{stage}: {e}");
    }
    let failed: Vec<String> = row["checks"]
        .as_object()
        .map(|m| {
            m.iter()
                .filter(|(_, v)| **v != json!(true))
                .map(|(k, _)| k.clone())
                .collect()
        })
        .unwrap_or_default();
    format!("failed {}", failed.join(", "))
}

/// Passed / failed counts per check.
fn check_counts(rows: &[Value]) -> BTreeMap<String, Value> {
    let mut counts: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    for r in rows {
        if let Some(m) = r["checks"].as_object() {
            for (k, v) in m {
                let c = counts.entry(k.clone()).or_default();
                if *v == json!(true) {
                    c.0 += 1;
                } else {
                    c.1 += 1;
                }
            }
        }
    }
    let errors = rows.iter().filter(|r| r["error"].is_string()).count();
    let mut out: BTreeMap<String, Value> = counts
        .into_iter()
        .map(|(k, (p, f))| (k, json!({"passed": p, "failed": f})))
        .collect();
    out.insert(
        "errors".into(),
        json!({"passed": rows.len() - errors, "failed": errors}),
    );
    out
}

/// A numeric measure of every row that has it.
fn measure(rows: &[Value], key: &str) -> Vec<f64> {
    rows.iter()
        .filter_map(|r| r["measures"][key].as_f64())
        .collect()
}

/// The Markdown summary.
fn markdown(s: &Value, rows: &[Value]) -> String {
    let mut md = String::new();
    let job = s["job"].as_str().unwrap_or("");
    md.push_str(&format!("# Validation of `{job}`\n\n"));
    md.push_str(&format!(
        "- sample: {} of {} ok items (`--sample {}`, `--seed {}`)\n",
        s["checked"],
        s["population"],
        s["sample"].as_str().unwrap_or(""),
        s["seed"]
    ));
    md.push_str(&format!(
        "- result: **{} passed, {} failed**\n",
        s["passed"], s["failed"]
    ));
    md.push_str(&format!(
        "- Hausdorff distance (voxels, larger of both ways): median {}, max {} (limit {})\n",
        fmt_opt(&s["hausdorff_voxels_median"]),
        fmt_opt(&s["hausdorff_voxels_max"]),
        s["max_hausdorff_voxels"]
    ));
    md.push_str(&format!(
        "- checked with pymeshlab {} on Python {}\n\n",
        s["versions"]["pymeshlab"].as_str().unwrap_or("?"),
        s["versions"]["python"].as_str().unwrap_or("?")
    ));
    md.push_str("| check | passed | failed |\n|---|---:|---:|\n");
    if let Some(m) = s["checks"].as_object() {
        for (k, v) in m {
            md.push_str(&format!("| {k} | {} | {} |\n", v["passed"], v["failed"]));
        }
    }
    let failures: Vec<&Value> = rows.iter().filter(|r| r["ok"] != json!(true)).collect();
    if !failures.is_empty() {
        md.push_str("\n## Failures\n\n| item | id | uri | what |\n|---:|---|---|---|\n");
        for r in failures {
            md.push_str(&format!(
                "| {} | `{}` | `{}` | {} |\n",
                r["item_index"],
                r["id"].as_str().unwrap_or(""),
                r["uri"].as_str().unwrap_or(""),
                failure_text(r).replace('|', "\\|")
            ));
        }
    }
    md.push_str("\nPer-item measures: `report.jsonl` (one JSON object per item).\n");
    md
}

/// A JSON number with 3 decimals, or `n/a`.
fn fmt_opt(v: &Value) -> String {
    v.as_f64().map_or("n/a".into(), |x| format!("{x:.3}"))
}

/// Writes `bytes` to a temporary name next to `path` and renames it into place.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, bytes).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("renaming to {}", path.display()))?;
    Ok(())
}
