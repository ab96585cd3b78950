//! What the shape signature adds to the conversion of real meshes, measured inside one process
//! as a job's worker sees it (one process converting item after item):
//!
//! - the conversion: load, the conversion stages and extraction, once per mesh;
//! - the pass over the output's triangles without the sample (what the quality facts need for
//!   the output's volume) and with it, followed by the signature read from it, ROUNDS times
//!   each in turn; the signature's cost is the difference of the two medians (`added`), and
//!   `stage` the median of the second, the whole pass counted (as the row's `signature` stage
//!   times it);
//! - `first`: the first call of the pass with the sample and the signature, on the mesh just
//!   extracted, as `sparc3d convert` (one process per mesh) sees it.
//!
//! One JSON line per mesh, then the median and largest shares of the conversion:
//!
//!     cargo run --release -p sparcubes --example signature_bench -- [--resolution R] \
//!         [--rounds K] MESH...

use sparcubes::products::shape_signature::{signature_of, surface_pass};
use sparcubes::TriMesh;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// Milliseconds `f` takes.
fn millis(f: impl FnOnce()) -> f64 {
    let t = Instant::now();
    f();
    t.elapsed().as_secs_f64() * 1e3
}

/// The middle of `v` (sorted in place).
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// One mesh's figures.
struct Row {
    triangles: usize,
    conversion_ms: f64,
    first_ms: f64,
    bare_ms: f64,
    stage_ms: f64,
}

/// Loads, converts and extracts `path` (timed), then times the passes (`rounds` each).
fn measure(path: &str, resolution: u32, rounds: usize) -> Result<Row, String> {
    let t = Instant::now();
    let loaded = sparcubes::io::load(&PathBuf::from(path)).map_err(|e| e.to_string())?;
    let params = sparcubes::Params::with_resolution(resolution);
    let conversion = sparcubes::convert(&loaded.mesh, &params).map_err(|e| e.to_string())?;
    let mesh: TriMesh = sparcubes::extract(&conversion.cubes);
    let conversion_ms = t.elapsed().as_secs_f64() * 1e3;
    let with = || {
        let pass = surface_pass(&mesh, true);
        std::hint::black_box(signature_of(&pass));
    };
    let first_ms = millis(with);
    let (mut bare, mut stage) = (Vec::new(), Vec::new());
    for _ in 0..rounds.max(1) {
        bare.push(millis(|| {
            std::hint::black_box(surface_pass(&mesh, false));
        }));
        stage.push(millis(with));
    }
    Ok(Row {
        triangles: mesh.triangles.len(),
        conversion_ms,
        first_ms,
        bare_ms: median(&mut bare),
        stage_ms: median(&mut stage),
    })
}

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1).peekable();
    let (mut resolution, mut rounds, mut meshes) = (256u32, 7usize, Vec::new());
    while let Some(a) = args.next() {
        let value = |args: &mut std::iter::Peekable<_>| -> Option<usize> {
            args.next().and_then(|v: String| v.parse().ok())
        };
        match a.as_str() {
            "--resolution" => match value(&mut args).and_then(|r| u32::try_from(r).ok()) {
                Some(r) => resolution = r,
                None => return usage(),
            },
            "--rounds" => match value(&mut args) {
                Some(r) => rounds = r,
                None => return usage(),
            },
            _ => meshes.push(a),
        }
    }
    if meshes.is_empty() {
        return usage();
    }
    let (mut added, mut stage, mut first) = (Vec::new(), Vec::new(), Vec::new());
    for path in &meshes {
        let row = match measure(path, resolution, rounds) {
            Ok(row) => row,
            Err(e) => {
                eprintln!("{path}: {e}");
                continue;
            }
        };
        let name = path.rsplit('/').next().unwrap_or(path);
        let share = |ms: f64| ms / row.conversion_ms;
        let added_ms = row.stage_ms - row.bare_ms;
        println!(
            "{{\"item\": \"{name}\", \"triangles\": {}, \"conversion_ms\": {:.2}, \"bare_ms\": \
             {:.3}, \"stage_ms\": {:.3}, \"added_ms\": {added_ms:.3}, \"first_ms\": {:.3}, \
             \"added_share\": {:.5}, \"stage_share\": {:.5}, \"first_share\": {:.5}}}",
            row.triangles,
            row.conversion_ms,
            row.bare_ms,
            row.stage_ms,
            row.first_ms,
            share(added_ms),
            share(row.stage_ms),
            share(row.first_ms)
        );
        added.push(share(added_ms));
        stage.push(share(row.stage_ms));
        first.push(share(row.first_ms));
    }
    if added.is_empty() {
        return ExitCode::FAILURE;
    }
    for (what, v) in [("added", added), ("stage", stage), ("first", first)] {
        let mut v = v;
        let over = v.iter().filter(|&&s| s > 0.05).count();
        let n = v.len();
        let max = v.iter().cloned().fold(0.0, f64::max);
        eprintln!(
            "{what}: median {:.2} %, max {:.2} %, {over} of {n} over 5 %",
            100.0 * median(&mut v),
            100.0 * max
        );
    }
    ExitCode::SUCCESS
}

fn usage() -> ExitCode {
    eprintln!("usage: signature_bench [--resolution R] [--rounds K] MESH...");
    ExitCode::FAILURE
}
