//! `sparc3d manifest build DIR -o manifest.(parquet|jsonl|csv)`: scan a folder for supported
//! meshes, hash them in parallel, and report identical duplicates (kept once).

use anyhow::Result;
use sparc3d_manifests::folder_scan::collect;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d manifest`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Sub,
}

#[derive(Debug, clap::Subcommand)]
enum Sub {
    /// Scan a folder for meshes and write a manifest (id = sha256 of the file).
    Build(BuildArgs),
}

/// Arguments of `sparc3d manifest build`.
#[derive(Debug, clap::Args)]
pub struct BuildArgs {
    /// Folder to scan (recursively).
    pub dir: PathBuf,
    /// Output manifest (.parquet, .jsonl or .csv).
    #[arg(short, long)]
    pub output: PathBuf,
}

/// Runs `sparc3d manifest`.
pub fn run(args: Args) -> Result<ExitCode> {
    let Sub::Build(args) = args.command;
    let c = collect(&args.dir)?;
    sparc3d_manifests::write::write(&c.records, &args.output)?;
    eprintln!(
        "{} meshes written to {} ({} identical duplicates left out, {} unreadable, {} \
         skipped: not regular files or names that are not UTF-8)",
        c.records.len(),
        args.output.display(),
        c.duplicates,
        c.unreadable,
        c.skipped
    );
    Ok(ExitCode::SUCCESS)
}
