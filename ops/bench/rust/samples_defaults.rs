//! The cost of one item's samples under the defaults of `[samples] enabled = true`: `old`, as
//! they were before sharp-near samples (124928 surface, 124928 sharp, 249856 near at σ 0.005 and
//! 0.05, 249856 volume), or `new` (`SampleParams::default()`: 204800 surface, 124928 sharp,
//! 600000 near, 262144 sharp-near, 249856 volume), then, with `new`, the 32768 farthest of the
//! surface points (a consumer's `fps_coarse_surface`). Prints the seconds of the conversion,
//! extraction, `sample` and `farthest_points` (wall and CPU):
//!
//!     cargo run --release -p sparcubes --example samples_defaults -- MESH [RESOLUTION] [old|new]

use sparcubes::samples::{farthest_points, sample, SampleParams};
use std::path::PathBuf;
use std::process::ExitCode;

#[path = "common/clock.rs"]
mod clock;
use clock::Clock;

/// Runs `f`, returning its result and "W s (C s CPU)".
fn timed<T>(f: impl FnOnce() -> T) -> (T, String) {
    let clock = Clock::start();
    let out = f();
    (out, clock.secs(3))
}

/// The defaults before sharp-near samples existed.
fn old_defaults() -> SampleParams {
    SampleParams {
        surface: 124_928,
        near: 249_856,
        sharp_near: 0,
        near_sigmas: vec![0.005, 0.05],
        sharp_near_sigmas: Vec::new(),
        ..SampleParams::default()
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(input) = args.first() else {
        eprintln!("usage: samples_defaults MESH [RESOLUTION] [old|new]");
        return ExitCode::FAILURE;
    };
    let resolution = args.get(1).and_then(|r| r.parse().ok()).unwrap_or(256u32);
    let new = args.get(2).is_none_or(|a| a != "old");
    let params = if new {
        SampleParams::default()
    } else {
        old_defaults()
    };
    let loaded = match sparcubes::io::load(&PathBuf::from(input)) {
        Ok(l) => l,
        Err(e) => {
            eprintln!("{input}: {e}");
            return ExitCode::FAILURE;
        }
    };
    let grid = sparcubes::Params::with_resolution(resolution);
    let (conversion, convert_s) = timed(|| sparcubes::convert(&loaded.mesh, &grid));
    let conversion = match conversion {
        Ok(c) => c,
        Err(e) => {
            eprintln!("{input}: {e}");
            return ExitCode::FAILURE;
        }
    };
    let (mesh, extract_s) = timed(|| sparcubes::extract(&conversion.cubes));
    let (drawn, sample_s) = timed(|| sample(&conversion.cubes, &mesh, &params));
    let drawn = match drawn {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{input}: {e}");
            return ExitCode::FAILURE;
        }
    };
    let fps = if new {
        let (chosen, s) = timed(|| farthest_points(&drawn.surface_points, 32_768));
        format!(
            "; farthest_points {} of {}: {s}",
            chosen.len(),
            drawn.surface_points.len()
        )
    } else {
        String::new()
    };
    println!(
        "{input} at {resolution}, {} defaults, {} threads: {} output triangles, {} sharp edges; \
         convert {convert_s}, extract {extract_s}, sample {sample_s} ({} points){fps}",
        if new { "new" } else { "old" },
        rayon::current_num_threads(),
        mesh.triangles.len(),
        drawn.sharp_edges,
        drawn.surface_points.len()
            + drawn.sharp_points.len()
            + drawn.near_points.len()
            + drawn.sharp_near_points.len()
            + drawn.volume_points.len(),
    );
    ExitCode::SUCCESS
}
