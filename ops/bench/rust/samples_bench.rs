//! Where the time of vector-set samples goes on one real mesh: conversion, extraction, the
//! closest-point tree, the near and volume distance queries, the grid sides, `sample` as a
//! whole (default parameters except the counts: 250k surface, near and volume points, no
//! sharp ones, as `ops/bench/samples_overhead.sh`), and the truncated SDF of
//! the sparse-SDF export (a 4-voxel band). Wall and
//! CPU seconds of each step:
//!
//!     cargo run --release -p sparcubes --example samples_bench -- MESH [RESOLUTION] [--no-layout]

use sparcubes::queries::closest::TriangleIndex;
use sparcubes::queries::sides::GridSides;
use sparcubes::samples::rng::Draw;
use sparcubes::samples::{sample, SampleParams};
use std::path::PathBuf;
use std::process::ExitCode;

#[path = "common/clock.rs"]
mod clock;
use clock::Clock;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(input) = args.first() else {
        eprintln!("usage: samples_bench MESH [RESOLUTION]");
        return ExitCode::FAILURE;
    };
    let resolution = args.get(1).and_then(|r| r.parse().ok()).unwrap_or(512u32);
    let t = Clock::start();
    let loaded = match sparcubes::io::load(&PathBuf::from(input)) {
        Ok(l) => l,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::FAILURE;
        }
    };
    let params = sparcubes::Params::with_resolution(resolution);
    let conversion = match sparcubes::convert(&loaded.mesh, &params) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::FAILURE;
        }
    };
    let convert_s = t.secs(2);
    let t = Clock::start();
    let mesh = sparcubes::extract(&conversion.cubes);
    let extract_s = t.secs(2);
    let count = 250_000u64;
    let (near, volume) = query_points(&mesh, resolution as f64, count);
    let t = Clock::start();
    let index = TriangleIndex::new(&mesh);
    let build_s = t.secs(2);
    let t = Clock::start();
    let a = index.closest_batch(&near);
    let near_s = t.secs(2);
    let t = Clock::start();
    let b = index.closest_batch(&volume);
    let volume_s = t.secs(2);
    let t = Clock::start();
    let sides = GridSides::new(&conversion.cubes);
    let (near_in, volume_in) = (sides.inside_batch(&near), sides.inside_batch(&volume));
    let inside = near_in.len() + volume_in.len();
    let sides_s = t.secs(2);
    let faces = format!(
        "near {}, volume {}",
        face_sides(&index, &near, &a, &near_in),
        face_sides(&index, &volume, &b, &volume_in)
    );
    let samples = SampleParams {
        surface: count as usize,
        sharp: 0,
        near: count as usize,
        volume: count as usize,
        ..SampleParams::default()
    };
    let t = Clock::start();
    let drawn = match sample(&conversion.cubes, &mesh, &samples) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::FAILURE;
        }
    };
    let sample_s = t.secs(2);
    // The truncated SDF (a 4-voxel band), unless `--no-layout` is given.
    let layout = if args.get(2).is_some_and(|a| a == "--no-layout") {
        String::new()
    } else {
        truncated_sdf_line(&conversion.cubes)
    };
    let check: f64 = a.iter().chain(&b).map(|c| c.distance).sum();
    println!(
        "{input} at {resolution}: {} triangles, {} threads; convert {convert_s}, \
         extract {extract_s}; tree {build_s}, {count} near queries {near_s}, \
         {count} volume queries {volume_s}, sides {sides_s} ({inside}; {faces}); \
         sample() {sample_s} ({} volume points; checksum {check:.6}){layout}",
        mesh.triangles.len(),
        rayon::current_num_threads(),
        drawn.volume_sdf.len(),
    );
    ExitCode::SUCCESS
}

/// `count` near points (mesh vertices moved by N(0, σ) per axis, σ = 0.005 and 0.05 in
/// normalized units) and `count` volume points (uniform in [-1.05, 1.05]³), both in grid units
/// of a grid of `n`, as `sample` queries them.
fn query_points(mesh: &sparcubes::TriMesh, n: f64, count: u64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let near = (0..count)
        .map(|i| {
            let d = Draw::new(1, 3, i);
            let v = mesh.positions[(i as usize * 7919) % mesh.positions.len()];
            let sigma = if i % 2 == 0 { 0.005 } else { 0.05 } * n / 2.0;
            [0, 1, 2].map(|a| v[a] as f64 + sigma * d.normal(a as u64))
        })
        .collect();
    let volume = (0..count)
        .map(|i| {
            let d = Draw::new(1, 4, i);
            [0, 1, 2].map(|k| (2.1 * d.uniform(k) - 1.05 + 1.0) * 0.5 * n)
        })
        .collect();
    (near, volume)
}

/// How often the closest triangle's face gives the side of a point, and how often that
/// disagrees with the grid's side.
fn face_sides(
    index: &TriangleIndex,
    points: &[[f64; 3]],
    closest: &[sparcubes::queries::closest::ClosestPoint],
    grid: &[bool],
) -> String {
    let mut answered = 0;
    let mut differ = 0;
    for ((p, c), g) in points.iter().zip(closest).zip(grid) {
        if let Some(f) = index.face_side(*p, c) {
            answered += 1;
            differ += usize::from(f != *g);
        }
    }
    format!("{answered} by the face, {differ} differ")
}

/// The truncated SDF of a 4-voxel band, timed, as the end of the printed line.
fn truncated_sdf_line(cubes: &sparcubes::SparseCubes) -> String {
    let t = Clock::start();
    let sdf = sparcubes::products::truncated_sdf::truncated_sdf(cubes, 4.0);
    format!(
        "; truncated sdf {} ({} points, checksum {:.3})",
        t.secs(2),
        sdf.sdf.len(),
        sdf.sdf.iter().map(|&v| v as f64).sum::<f64>(),
    )
}
