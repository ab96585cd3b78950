//! `sparc3d convert IN -o OUT`: one mesh through Sparcubes and back to a watertight mesh.

use anyhow::Context;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d convert`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input mesh (OBJ, PLY, STL, OFF, glTF, GLB).
    pub input: PathBuf,
    /// Output mesh (.ply, .obj, .stl, .glb).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Grid resolution N (cells per axis).
    #[arg(long, default_value_t = 512)]
    pub resolution: u32,
    /// Turn off the deformation of active vertices.
    #[arg(long)]
    pub no_deform: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `sparc3d convert`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let loaded = sparcubes::io::load(&args.input)
        .with_context(|| format!("loading {}", args.input.display()))?;
    let mut params = sparcubes::Params::with_resolution(args.resolution);
    params.deform = !args.no_deform;
    let conversion = sparcubes::convert(&loaded.mesh, &params)
        .with_context(|| format!("converting {}", args.input.display()))?;
    let mesh = sparcubes::extract(&conversion.cubes);
    sparcubes::io::save(&mesh, &args.output)
        .with_context(|| format!("writing {}", args.output.display()))?;
    Ok(ExitCode::SUCCESS)
}
