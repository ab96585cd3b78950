//! `sparc3d bench DIR_OR_MANIFEST [--resolution 512,1024] [--json]`: converts every mesh once
//! per resolution, each in its own `sparc3d bench-one` subprocess (so peak RSS is per mesh and
//! a crash, an out-of-memory kill or a timeout is one failed row, not a dead benchmark), after
//! one warm-up conversion of the first mesh. Prints median / p95 / max of the total time, of
//! every stage, of CPU seconds, peak RSS, active vertices and compressed bytes per active
//! vertex, and the throughput in meshes per hour per core.

pub mod dedup;
pub mod measured;
pub mod one;

use crate::util::units::parse_duration;
use anyhow::{bail, Context, Result};
use one::BenchRow;
use serde::Serialize;
use sparc3d_manifests::table as manifest_io;
use sparc3d_workers::isolate::process::{Process, ProcessOptions};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};
use std::time::{Duration, Instant};

/// Arguments of `sparc3d bench`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A folder (scanned recursively for supported meshes), a manifest (.csv, .jsonl or
    /// .parquet with a `uri` or `path` column) or a single mesh.
    pub input: PathBuf,
    /// Grid resolutions, comma-separated.
    #[arg(long, value_delimiter = ',',
          default_values_t = [crate::flags::resolution::default_resolution()])]
    pub resolution: Vec<u32>,
    /// Print every row and the summary as one JSON document instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Also write every row to this JSON Lines file, one line per mesh as it finishes.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Threads per conversion (sets RAYON_NUM_THREADS of each subprocess); default: all cores.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Time limit per mesh (e.g. 90, 30s, 10m); a mesh over it is killed and counted failed.
    #[arg(long, default_value = "10m", value_parser = parse_duration)]
    pub timeout: f64,
    /// Benchmark only the first N meshes (in path order).
    #[arg(long)]
    pub limit: Option<usize>,
    /// Skip the warm-up conversion.
    #[arg(long)]
    pub no_warmup: bool,
    #[command(flatten)]
    pub measured: measured::MeasuredConversion,
}

/// Median, 95th percentile (nearest rank), maximum and mean of a sample.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Spread {
    /// Median (mean of the two middle values for an even count).
    pub median: f64,
    /// 95th percentile, nearest rank.
    pub p95: f64,
    /// Maximum.
    pub max: f64,
    /// Arithmetic mean.
    pub mean: f64,
}

impl Spread {
    /// The spread of `values` (all zero when empty).
    pub fn of(values: &[f64]) -> Self {
        let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return Self::default();
        }
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = crate::util::stats::median(&v).unwrap_or_default();
        let rank = ((0.95 * n as f64).ceil() as usize).clamp(1, n);
        Self {
            median,
            p95: v[rank - 1],
            max: v[n - 1],
            mean: v.iter().sum::<f64>() / n as f64,
        }
    }
}

/// The summary of one resolution over the converted meshes.
#[derive(Debug, Clone, Serialize)]
pub struct ResolutionSummary {
    /// Grid resolution N.
    pub resolution: u32,
    /// Meshes attempted.
    pub meshes: usize,
    /// Meshes converted.
    pub ok: usize,
    /// Meshes failed (error, crash, out of memory, timeout).
    pub failed: usize,
    /// Seconds inside the converting process (sum of the stages).
    pub total_seconds: Spread,
    /// Wall seconds of the subprocess, start-up included.
    pub process_seconds: Spread,
    /// User + system CPU seconds of the subprocess.
    pub cpu_seconds: Spread,
    /// Seconds per stage, in stage order.
    pub stages: Vec<(String, Spread)>,
    /// Peak RSS per mesh (kernel `ru_maxrss`), bytes.
    pub peak_rss_bytes: Spread,
    /// Tracing seconds a condition view, per mesh (`--renders`; all zero without).
    pub seconds_per_view: Spread,
    /// Active vertices per mesh.
    pub active_vertices: Spread,
    /// Output triangles per mesh.
    pub output_faces: Spread,
    /// Compressed tensor bytes per active vertex, per mesh.
    pub bytes_per_active_vertex: Spread,
    /// Compressed tensor bytes of all meshes over their active vertices.
    pub bytes_per_active_vertex_overall: f64,
    /// Threads per conversion.
    pub threads: usize,
    /// Meshes per hour per core from wall time: 3600 × ok / (Σ total seconds × threads).
    pub meshes_per_hour_per_core: f64,
    /// Meshes per hour per core from CPU time: 3600 × ok / Σ CPU seconds (load-independent).
    pub meshes_per_cpu_hour: f64,
}

/// What `--json` prints.
#[derive(Debug, Serialize)]
struct Report<'a> {
    rows: &'a [BenchRow],
    summary: &'a [ResolutionSummary],
}

/// The meshes named by `input`: a folder's supported files, a manifest's paths, or one mesh.
fn collect_inputs(input: &Path) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    if input.is_dir() {
        sparc3d_manifests::folder_scan::scan(input, &mut files)?;
    } else if sparcubes::io::Format::from_extension(input).is_some() {
        files.push(input.to_path_buf());
    } else if input.is_file() {
        files = manifest_io::read(input, None)
            .with_context(|| format!("reading manifest {}", input.display()))?
            .records
            .into_iter()
            .map(|r| PathBuf::from(r.uri))
            .collect();
    } else {
        bail!("{}: no such folder, manifest or mesh", input.display());
    }
    if files.is_empty() {
        bail!("{}: no meshes found", input.display());
    }
    Ok(files)
}

/// Bytes of a failed mesh's stderr kept to name the failure (its last lines).
const STDERR_TAIL_BYTES: usize = 16 << 10;

fn describe_status(status: Option<i32>) -> String {
    match status {
        None => "the process could not be waited for".into(),
        Some(s) if libc::WIFSIGNALED(s) => {
            let sig = libc::WTERMSIG(s);
            let name = match sig {
                libc::SIGKILL => " (SIGKILL: out of memory?)",
                libc::SIGSEGV => " (SIGSEGV: stack overflow?)",
                libc::SIGABRT => " (SIGABRT: abort, allocation failure?)",
                _ => "",
            };
            format!("killed by signal {sig}{name}")
        }
        Some(s) if libc::WIFEXITED(s) => format!("exited with status {}", libc::WEXITSTATUS(s)),
        Some(s) => format!("ended with wait status {s}"),
    }
}

fn last_lines(text: &str, n: usize) -> String {
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    lines[lines.len().saturating_sub(n)..].join(" | ")
}

/// Converts one mesh in a `bench-one` subprocess and returns its row; every failure of the
/// mesh (error, crash, timeout, unreadable answer) is a row with `ok: false`.
fn bench_mesh(exe: &Path, path: &Path, resolution: u32, args: &Args) -> BenchRow {
    let failed = |error: String| BenchRow {
        path: path.display().to_string(),
        resolution,
        ok: false,
        error: Some(error),
        ..Default::default()
    };
    let mut cmd = Command::new(exe);
    cmd.arg("bench-one")
        .arg(path)
        .arg("--resolution")
        .arg(resolution.to_string())
        .args(args.measured.as_flags())
        .stdin(Stdio::null())
        .stdout(Stdio::piped());
    if let Some(t) = args.threads {
        cmd.env("RAYON_NUM_THREADS", t.to_string());
    }
    // The conversion dies with the benchmark instead of running on as an orphan.
    let options = ProcessOptions {
        parent_death_signal: Some(libc::SIGKILL),
        ..Default::default()
    };
    let start = Instant::now();
    let mut child = match Process::spawn(&mut cmd, &options) {
        Ok(c) => c,
        Err(e) => return failed(format!("starting {}: {e}", exe.display())),
    };
    let stdout = child.take_stdout().map(|mut s| {
        std::thread::spawn(move || {
            let mut buf = String::new();
            let _ = s.read_to_string(&mut buf);
            buf
        })
    });
    let waited = child.wait_with_usage(Duration::from_secs_f64(args.timeout));
    let process_seconds = start.elapsed().as_secs_f64();
    let stdout = stdout.and_then(|h| h.join().ok()).unwrap_or_default();
    let stderr = child.stderr_tail(STDERR_TAIL_BYTES);

    let exited_ok = waited.success();
    let parsed = stdout
        .lines()
        .rev()
        .find(|l| l.trim_start().starts_with('{'))
        .map(serde_json::from_str::<BenchRow>);
    let mut row = match (waited.timed_out, exited_ok, parsed) {
        (true, _, _) => failed(format!("timed out after {:.0} s", args.timeout)),
        (false, true, Some(Ok(row))) => row,
        (false, true, Some(Err(e))) => failed(format!("unreadable answer: {e}")),
        (false, _, _) => {
            let tail = last_lines(&stderr, 3);
            failed(format!(
                "{}{}{}",
                describe_status(waited.status),
                if tail.is_empty() { "" } else { ": " },
                tail
            ))
        }
    };
    row.process_seconds = process_seconds;
    row.cpu_user_seconds = waited.user_seconds;
    row.cpu_sys_seconds = waited.sys_seconds;
    row.max_rss_bytes = waited.max_rss_bytes.or(row.peak_rss_bytes);
    row
}

/// Summarises the rows of one resolution.
pub fn summarise(rows: &[BenchRow], resolution: u32, threads: usize) -> ResolutionSummary {
    let all: Vec<&BenchRow> = rows.iter().filter(|r| r.resolution == resolution).collect();
    let ok: Vec<&BenchRow> = all.iter().copied().filter(|r| r.ok).collect();
    let spread =
        |f: &dyn Fn(&BenchRow) -> f64| Spread::of(&ok.iter().map(|r| f(r)).collect::<Vec<_>>());
    let mut stage_names: Vec<String> = Vec::new();
    for r in &ok {
        for (k, _) in &r.stages {
            if !stage_names.contains(k) {
                stage_names.push(k.clone());
            }
        }
    }
    let stages = stage_names
        .into_iter()
        .map(|name| {
            let s = spread(&|r: &BenchRow| {
                r.stages
                    .iter()
                    .filter(|(k, _)| *k == name)
                    .map(|(_, v)| v)
                    .sum()
            });
            (name, s)
        })
        .collect();
    let total_seconds: f64 = ok.iter().map(|r| r.total_seconds).sum();
    let cpu_seconds: f64 = ok
        .iter()
        .map(|r| r.cpu_user_seconds + r.cpu_sys_seconds)
        .sum();
    let bytes: u64 = ok.iter().map(|r| r.tensor_bytes.total()).sum();
    let active: u64 = ok.iter().map(|r| r.active_vertices).sum();
    let per = |num: f64, den: f64| if den > 0.0 { num / den } else { 0.0 };
    ResolutionSummary {
        resolution,
        meshes: all.len(),
        ok: ok.len(),
        failed: all.len() - ok.len(),
        total_seconds: spread(&|r| r.total_seconds),
        process_seconds: spread(&|r| r.process_seconds),
        cpu_seconds: spread(&|r| r.cpu_user_seconds + r.cpu_sys_seconds),
        stages,
        peak_rss_bytes: spread(&|r| r.max_rss_bytes.or(r.peak_rss_bytes).unwrap_or(0) as f64),
        seconds_per_view: spread(&|r| r.render_views.map_or(0.0, |v| v.1)),
        active_vertices: spread(&|r| r.active_vertices as f64),
        output_faces: spread(&|r| r.output_faces as f64),
        bytes_per_active_vertex: spread(&|r| r.bytes_per_active_vertex),
        bytes_per_active_vertex_overall: per(bytes as f64, active as f64),
        threads,
        meshes_per_hour_per_core: per(3600.0 * ok.len() as f64, total_seconds * threads as f64),
        meshes_per_cpu_hour: per(3600.0 * ok.len() as f64, cpu_seconds),
    }
}

fn print_summary(s: &ResolutionSummary, rows: &[BenchRow]) {
    println!(
        "\n{}³: {} meshes, {} converted, {} failed; {} thread(s) per conversion",
        s.resolution, s.meshes, s.ok, s.failed, s.threads
    );
    println!("  {:<26} {:>10} {:>10} {:>10}", "", "median", "p95", "max");
    let line = |name: &str, sp: &Spread, unit: &str, scale: f64, prec: usize| {
        println!(
            "  {:<26} {:>10} {:>10} {:>10}",
            format!("{name} ({unit})"),
            format!("{:.prec$}", sp.median / scale),
            format!("{:.prec$}", sp.p95 / scale),
            format!("{:.prec$}", sp.max / scale),
        );
    };
    line("total", &s.total_seconds, "s", 1.0, 3);
    for (name, sp) in &s.stages {
        line(&format!("  {name}"), sp, "s", 1.0, 3);
    }
    if s.seconds_per_view.max > 0.0 {
        line("  a condition view", &s.seconds_per_view, "s", 1.0, 3);
    }
    line("process wall", &s.process_seconds, "s", 1.0, 3);
    line("cpu user+sys", &s.cpu_seconds, "s", 1.0, 3);
    line("peak RSS", &s.peak_rss_bytes, "MB", 1e6, 1);
    line("active vertices", &s.active_vertices, "k", 1e3, 1);
    line("output faces", &s.output_faces, "k", 1e3, 1);
    line(
        "zstd bytes/active vertex",
        &s.bytes_per_active_vertex,
        "B",
        1.0,
        2,
    );
    println!(
        "  bytes per active vertex over all meshes: {:.2}; meshes per hour per core: {:.0} \
         (wall), {:.0} (CPU)",
        s.bytes_per_active_vertex_overall, s.meshes_per_hour_per_core, s.meshes_per_cpu_hour
    );
    for r in rows
        .iter()
        .filter(|r| r.resolution == s.resolution && !r.ok)
    {
        println!(
            "  failed: {}: {}",
            r.path,
            r.error.as_deref().unwrap_or("unknown")
        );
    }
}

/// Runs `sparc3d bench`.
pub fn run(args: Args) -> Result<ExitCode> {
    if args.resolution.is_empty() {
        bail!("--resolution needs at least one value");
    }
    let mut files = collect_inputs(&args.input)?;
    if let Some(n) = args.limit {
        files.truncate(n);
    }
    let exe = std::env::current_exe().context("locating the sparc3d executable")?;
    let threads = args.threads.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    let mut out = match &args.out {
        Some(p) => Some(std::io::BufWriter::new(
            std::fs::File::create(p).with_context(|| format!("creating {}", p.display()))?,
        )),
        None => None,
    };
    if let (false, Some(first)) = (args.no_warmup, files.first()) {
        eprintln!("warm-up: {} at {}³", first.display(), args.resolution[0]);
        let _ = bench_mesh(&exe, first, args.resolution[0], &args);
    }
    let mut rows: Vec<BenchRow> = Vec::with_capacity(files.len() * args.resolution.len());
    let total = files.len() * args.resolution.len();
    for &res in &args.resolution {
        for file in &files {
            let row = bench_mesh(&exe, file, res, &args);
            let name = file
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| file.display().to_string());
            if row.ok {
                eprintln!(
                    "[{}/{total}] {res}³ {name}: {:.3} s, {} active vertices, {:.0} MB",
                    rows.len() + 1,
                    row.total_seconds,
                    row.active_vertices,
                    row.max_rss_bytes.unwrap_or(0) as f64 / 1e6
                );
            } else {
                eprintln!(
                    "[{}/{total}] {res}³ {name}: FAILED: {}",
                    rows.len() + 1,
                    row.error.as_deref().unwrap_or("unknown")
                );
            }
            if let (Some(w), Some(p)) = (out.as_mut(), args.out.as_ref()) {
                let line = serde_json::to_string(&row).context("serialising a row")?;
                writeln!(w, "{line}")
                    .and_then(|_| w.flush())
                    .with_context(|| format!("writing {}", p.display()))?;
            }
            rows.push(row);
        }
    }
    let summary: Vec<ResolutionSummary> = args
        .resolution
        .iter()
        .map(|&r| summarise(&rows, r, threads))
        .collect();
    if args.json {
        let doc = serde_json::to_string_pretty(&Report {
            rows: &rows,
            summary: &summary,
        })
        .context("serialising the report")?;
        println!("{doc}");
    } else {
        for s in &summary {
            print_summary(s, &rows);
        }
    }
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_nearest_rank() {
        let v: Vec<f64> = (1..=20).map(f64::from).collect();
        let s = Spread::of(&v);
        assert_eq!(s.median, 10.5);
        assert_eq!(s.p95, 19.0);
        assert_eq!(s.max, 20.0);
        let one = Spread::of(&[3.0]);
        assert_eq!((one.median, one.p95, one.max), (3.0, 3.0, 3.0));
        assert_eq!(Spread::of(&[]).max, 0.0);
    }
}
