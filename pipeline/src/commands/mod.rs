//! One module per subcommand; [`run`] dispatches. Each module has an `Args` struct (clap) and
//! a `run(args) -> anyhow::Result<ExitCode>`.

pub mod convert;
pub mod eval;
pub mod fill_holes;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// sparc3d: raw meshes → watertight sparse cube tensors (Sparcubes), sharded into Parquet.
#[derive(Debug, Parser)]
#[command(name = "sparc3d", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Convert one mesh to sparse cubes and write the extracted watertight mesh.
    Convert(convert::Args),
    /// Fill the holes of a mesh (e.g. decoded from a VAE) by smallest-angle ear filling.
    FillHoles(fill_holes::Args),
    /// Measure a mesh against its source: Chamfer, normal consistency, F1, components, offset.
    Eval(eval::Args),
}

/// Runs the parsed command line and returns the process exit code.
pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Convert(args) => convert::run(args),
        Command::FillHoles(args) => fill_holes::run(args),
        Command::Eval(args) => eval::run(args),
    }
}
