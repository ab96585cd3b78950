//! The library in a few lines: load a mesh, convert it to sparse cubes, extract the watertight
//! mesh in the source frame and save it.
//!
//! `cargo run --release -p sparcubes --example to_watertight -- IN OUT [RESOLUTION]`

use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(input), Some(output)) = (args.first(), args.get(1)) else {
        eprintln!("usage: to_watertight IN OUT [RESOLUTION]");
        return ExitCode::FAILURE;
    };
    let resolution = match args.get(2).map(|r| r.parse::<u32>()) {
        None => 256,
        Some(Ok(r)) => r,
        Some(Err(e)) => {
            eprintln!("resolution: {e}");
            return ExitCode::FAILURE;
        }
    };
    let run = || -> Result<usize, sparcubes::Error> {
        let loaded = sparcubes::io::load(&PathBuf::from(input))?;
        let params = sparcubes::Params::with_resolution(resolution);
        let conversion = sparcubes::convert(&loaded.mesh, &params)?;
        let mesh = sparcubes::extract::extract_to_source(&conversion.cubes);
        sparcubes::io::save(&mesh, &PathBuf::from(output))?;
        Ok(mesh.triangles.len())
    };
    match run() {
        Ok(faces) => {
            println!("{input} -> {output}: {faces} faces");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
