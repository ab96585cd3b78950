//! One module per subcommand; [`run()`] dispatches. Each module has an `Args` struct (clap) and
//! a `run(args) -> anyhow::Result<ExitCode>`.

pub mod add;
pub mod bench;
pub mod convert;
pub mod dedup;
pub mod eval;
pub mod export;
pub mod extract;
pub mod failures;
pub mod fill_holes;
pub mod generate;
pub mod init;
pub mod inspect;
pub mod item_worker;
pub mod ls;
pub mod manifest;
pub mod preview;
pub mod render;
pub mod report;
pub mod retry;
pub mod run;
pub mod show;
pub mod status;
pub mod submit;
pub mod validate;
pub mod verify;
pub mod work;

use anyhow::Context;
use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Checks the conversion parameters a command built from its flags (`convert`, `preview`);
/// the error names the setting out of range.
pub(crate) fn check_params(params: &sparcubes::Params) -> anyhow::Result<()> {
    params
        .validate()
        .map_err(|e| anyhow::anyhow!("{e}"))
        .context("checking the conversion parameters")
}

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
    /// Extract the mesh of sparse cubes in a tensor file or shard (e.g. decoded by a VAE).
    Extract(extract::Args),
    /// Measure a mesh against its source: Chamfer, normal consistency, F1, components, offset.
    Eval(eval::Args),
    /// Build a manifest by scanning a folder for meshes.
    Manifest(manifest::Args),
    /// Create a job folder: freeze the manifest, assign shards, fix the config.
    Init(init::Args),
    /// Grow a job with the items of a folder or manifest it does not have yet (new shards).
    Add(add::Args),
    /// Run a job locally with N worker processes, with progress; resumable. With --job OUT,
    /// make the job from a folder of meshes or a manifest first.
    Run(run::Args),
    /// Process shards of a job (one process; for clusters: --shard-index or --array).
    Work(work::Args),
    /// Show a job's progress: shards, items, throughput, ETA, errors.
    Status(status::Args),
    /// Submit a job's unfinished shards to a cluster scheduler (Slurm array jobs).
    Submit(submit::Args),
    /// List a job's items with their ids, status and source file (`--failed`: only failures).
    Ls(ls::Args),
    /// List a job's failed items with the reasons.
    Failures(failures::Args),
    /// Queue a job's failed items (optionally of one class) to be converted again.
    Retry(retry::Args),
    /// Describe a shard or a job: rows, bytes per column, percentiles, content digest.
    Inspect(inspect::Args),
    /// Decode one item of a job and write its mesh.
    Show(show::Args),
    /// Group a job's near-duplicates (same shape up to motion, scale, mirroring and
    /// triangulation) by their shape signatures; writes nothing.
    Dedup(dedup::Args),
    /// Write a job's items in the layout another codebase's loader reads: Hunyuan3D-2.1, Dora,
    /// Step1X-3D, TripoSG, TRELLIS.2, Direct3D-S2, cubvh, or our vector-set samples.
    Export(export::Args),
    /// Hash every finished shard against its completion record; move damaged ones aside.
    Verify(verify::Args),
    /// Check a reproducible sample of a job's outputs with pymeshlab; writes a report.
    #[command(after_help = crate::check::validation::PYTHON_HELP)]
    Validate(validate::Args),
    /// Render a mesh (or a job's item) and its converted output side by side to a PNG.
    Preview(preview::Args),
    /// Render a mesh's condition views as TRELLIS or TRELLIS.2 lays them out (RGBA PNGs and
    /// transforms.json), on the CPU.
    Render(render::Args),
    /// Write one static HTML page about a job: status, histograms, previews, failures.
    Report(report::Args),
    /// Write the man page, the shell completions (bash, zsh, fish) or the command reference
    /// (docs/CLI.md), all from the definitions `--help` prints.
    Generate(generate::Args),
    /// Benchmark conversion over a folder or manifest: time per stage, peak memory, size.
    Bench(bench::Args),
    /// Benchmark `dedup`'s grouping on N synthetic shape signatures (default a million).
    BenchDedup(bench::dedup::Args),
    /// Internal: converts one mesh for `bench` and prints one JSON row.
    #[command(hide = true)]
    BenchOne(bench::one::Args),
    /// Internal: the isolated process converting items for `work`.
    #[command(hide = true)]
    ItemWorker(item_worker::Args),
}

/// Runs the parsed command line and returns the process exit code.
pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Convert(args) => convert::run(args),
        Command::FillHoles(args) => fill_holes::run(args),
        Command::Extract(args) => extract::run(args),
        Command::Eval(args) => eval::run(args),
        Command::Manifest(args) => manifest::run(args),
        Command::Init(args) => init::run(args),
        Command::Add(args) => add::run(args),
        Command::Run(args) => run::run(args),
        Command::Work(args) => work::run(args),
        Command::Status(args) => status::run(args),
        Command::Submit(args) => submit::run(args),
        Command::Ls(args) => ls::run(args),
        Command::Failures(args) => failures::run(args),
        Command::Retry(args) => retry::run(args),
        Command::Inspect(args) => inspect::run(args),
        Command::Show(args) => show::run(args),
        Command::Dedup(args) => dedup::run(args),
        Command::Export(args) => export::run(args),
        Command::Verify(args) => verify::run(args),
        Command::Validate(args) => validate::run(args),
        Command::Preview(args) => preview::run(args),
        Command::Render(args) => render::run(args),
        Command::Report(args) => report::run(args),
        Command::Generate(args) => generate::run(args),
        Command::Bench(args) => bench::run(args),
        Command::BenchDedup(args) => bench::dedup::run(args),
        Command::BenchOne(args) => bench::one::run(args),
        Command::ItemWorker(args) => item_worker::run(args),
    }
}
