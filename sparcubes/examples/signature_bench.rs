//! Where the time of the shape signature goes on one real mesh's output: the pass over every
//! triangle without the sample (the volume, which the quality facts measure anyway) and with
//! it, and the signature read from the pass; the first call's time (as a job's one call sees
//! it) and the best of ROUNDS each, in milliseconds, beside the conversion's and the
//! extraction's seconds:
//!
//!     cargo run --release -p sparcubes --example signature_bench -- MESH [RESOLUTION] [ROUNDS]

use sparcubes::products::shape_signature::{signature_of, surface_pass};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// The first and the best wall time of `rounds` (at least one) calls of `f`, in
/// milliseconds, and its last value.
fn timed<T>(rounds: usize, mut f: impl FnMut() -> T) -> (f64, f64, T) {
    let t = Instant::now();
    let mut value = f();
    let first = t.elapsed().as_secs_f64() * 1e3;
    let mut best = first;
    for _ in 1..rounds {
        let t = Instant::now();
        value = f();
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    (first, best, value)
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(input) = args.first() else {
        eprintln!("usage: signature_bench MESH [RESOLUTION] [ROUNDS]");
        return ExitCode::FAILURE;
    };
    let resolution = args.get(1).and_then(|r| r.parse().ok()).unwrap_or(256u32);
    let rounds = args.get(2).and_then(|r| r.parse().ok()).unwrap_or(5usize);
    let loaded = match sparcubes::io::load(&PathBuf::from(input)) {
        Ok(l) => l,
        Err(e) => {
            eprintln!("{input}: {e}");
            return ExitCode::FAILURE;
        }
    };
    let t = Instant::now();
    let params = sparcubes::Params::with_resolution(resolution);
    let conversion = match sparcubes::convert(&loaded.mesh, &params) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("{input}: {e}");
            return ExitCode::FAILURE;
        }
    };
    let convert_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let mesh = sparcubes::extract(&conversion.cubes);
    let extract_s = t.elapsed().as_secs_f64();
    let (sampled_first, sampled_best, pass) = timed(rounds, || surface_pass(&mesh, true));
    let (bare_first, bare_best, _) = timed(rounds, || surface_pass(&mesh, false));
    let (signature_first, signature_best, _) = timed(rounds, || signature_of(&pass));
    println!(
        "{input}: {} triangles; convert {convert_s:.3} s, extract {extract_s:.3} s; pass with \
         the sample {sampled_first:.2} ms first, {sampled_best:.2} best; without \
         {bare_first:.2} / {bare_best:.2}; signature from it {signature_first:.2} / \
         {signature_best:.2}",
        mesh.triangles.len()
    );
    ExitCode::SUCCESS
}
