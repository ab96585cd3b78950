//! The attribute stage's time on real textured meshes, measured inside one process: each mesh
//! is loaded and converted once (timed: the conversion), its appearance read once (timed),
//! then the cells' attributes sampled ROUNDS times (`sparcubes::attributes::sample`, median).
//! Prints one JSON line per mesh (cells, cells filled from the closest point, the
//! milliseconds of the conversion, of reading the materials and of the sampling, the
//! sampling's CPU milliseconds a round over all threads, which a busy shared machine disturbs
//! less than the wall time, and a hash of the bytes, so that two builds can be compared for
//! speed and for identical output), then the median share of the conversion:
//!
//!     cargo run --release -p sparcubes --example attributes_bench -- [--resolution R] \
//!         [--rounds K] MESH...
//!
//! The share here leaves out reading the materials (the stage's `materials::read`: 2–40 ms on
//! the items of docs/PERFORMANCE.md, the most where a 2048² PNG is decoded) and counts the
//! conversion without extraction, so it is not the row's `attributes` share; it is for
//! comparing builds of the sampling itself.

use sparcubes::attributes::{sample, CellAttributes};
use sparcubes::io::Buffers;
use std::hash::{Hash, Hasher};
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

/// The middle of `v` (sorted in place).
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// CPU seconds this process has used (all threads), from `/proc/self/stat`; 0 where that
/// cannot be read.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    // The fields after the command's closing parenthesis; utime and stime are the 12th and
    // 13th of them, in clock ticks (100 a second on Linux).
    let after = stat.rsplit(')').next().unwrap_or("");
    let ticks: f64 = after
        .split_whitespace()
        .skip(11)
        .take(2)
        .filter_map(|f| f.parse::<f64>().ok())
        .sum();
    ticks / 100.0
}

/// A hash of every byte of the attributes (the same bytes give the same hash).
fn digest(a: &CellAttributes) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    (&a.base_color, &a.metallic, &a.roughness, &a.alpha).hash(&mut h);
    h.finish()
}

/// Converts `path` at `n`³ and times the sampling `rounds` times: one JSON line.
fn measure(
    path: &Path,
    n: u32,
    rounds: usize,
) -> Result<(String, f64), Box<dyn std::error::Error>> {
    let t = Instant::now();
    let loaded = sparcubes::io::load(path)?;
    let cubes = sparcubes::convert(&loaded.mesh, &sparcubes::Params::with_resolution(n))?.cubes;
    let conversion_ms = t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let bytes = std::fs::read(path)?;
    let app = sparcubes::materials::read(&bytes, path, Buffers::Folder)?;
    let read_ms = t.elapsed().as_secs_f64() * 1e3;
    let mut times = Vec::new();
    let mut out = CellAttributes::default();
    let cpu = cpu_seconds();
    for _ in 0..rounds.max(1) {
        let t = Instant::now();
        out = sample(&cubes, &app);
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let cpu_ms = (cpu_seconds() - cpu) * 1e3 / rounds.max(1) as f64;
    let sample_ms = median(&mut times);
    let share = sample_ms / conversion_ms;
    let name = path
        .file_name()
        .map_or_else(String::new, |s| s.to_string_lossy().into());
    let line = serde_json::json!({
        "item": name,
        "cells": cubes.cells.len(),
        "nearest_cells": out.nearest_cells,
        "conversion_ms": conversion_ms,
        "read_ms": read_ms,
        "sample_ms": sample_ms,
        "cpu_ms": cpu_ms,
        "share": share,
        "digest": format!("{:016x}", digest(&out)),
    });
    Ok((line.to_string(), share))
}

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let (mut resolution, mut rounds, mut meshes) = (512u32, 5usize, Vec::new());
    while let Some(a) = args.next() {
        let mut value = || args.next().and_then(|v| v.parse::<usize>().ok());
        match a.as_str() {
            "--resolution" => match value().and_then(|r| u32::try_from(r).ok()) {
                Some(r) => resolution = r,
                None => return usage(),
            },
            "--rounds" => match value() {
                Some(r) => rounds = r,
                None => return usage(),
            },
            _ => meshes.push(a),
        }
    }
    if meshes.is_empty() {
        return usage();
    }
    let mut shares = Vec::new();
    for path in &meshes {
        match measure(Path::new(path), resolution, rounds) {
            Ok((line, share)) => {
                println!("{line}");
                shares.push(share);
            }
            Err(e) => eprintln!("{path}: {e}"),
        }
    }
    if shares.is_empty() {
        return ExitCode::FAILURE;
    }
    eprintln!(
        "sampling over conversion: median {:.1} % of {} meshes",
        100.0 * median(&mut shares),
        shares.len()
    );
    ExitCode::SUCCESS
}

fn usage() -> ExitCode {
    eprintln!("usage: attributes_bench [--resolution R] [--rounds K] MESH...");
    ExitCode::FAILURE
}
