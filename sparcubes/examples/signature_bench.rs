//! Where the time of the shape signature goes on one real mesh's output: its volume (one pass
//! over every triangle, which the quality facts measure anyway) and the signature read from
//! the volume and a sample of the triangles; the best of ROUNDS each, in milliseconds, beside
//! the conversion's and the extraction's seconds:
//!
//!     cargo run --release -p sparcubes --example signature_bench -- MESH [RESOLUTION] [ROUNDS]

use sparcubes::products::shape_signature::shape_signature_with;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// The best wall time of `rounds` calls of `f`, in milliseconds, and its last value.
fn best<T>(rounds: usize, mut f: impl FnMut() -> T) -> (f64, Option<T>) {
    let mut out = (f64::INFINITY, None);
    for _ in 0..rounds {
        let t = Instant::now();
        let v = f();
        out.0 = out.0.min(t.elapsed().as_secs_f64() * 1e3);
        out.1 = Some(v);
    }
    out
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
    let (volume_ms, volume) = best(rounds, || mesh.signed_volume());
    let volume = volume.unwrap_or_default();
    let (signature_ms, _) = best(rounds, || shape_signature_with(&mesh, volume));
    println!(
        "{input}: {} triangles; convert {convert_s:.3} s, extract {extract_s:.3} s; volume \
         {volume_ms:.2} ms; signature from it {signature_ms:.2} ms",
        mesh.triangles.len()
    );
    ExitCode::SUCCESS
}
