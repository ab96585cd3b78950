//! `sparc3d item-worker` (hidden): the isolated process that converts items for `work`.

use anyhow::Result;
use std::process::ExitCode;

/// Arguments of the item worker.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Address-space limit in bytes (0: none).
    #[arg(long, default_value_t = 0)]
    pub memory_bytes: u64,
    /// Pid of the supervising `work` process.
    #[arg(long, default_value_t = 0)]
    pub parent_pid: u32,
}

/// Runs the item worker loop.
pub fn run(args: Args) -> Result<ExitCode> {
    let code =
        sparc3d_workers::isolate::child::main(sparc3d_workers::isolate::child::ChildOptions {
            memory_bytes: args.memory_bytes,
            parent_pid: args.parent_pid,
        });
    Ok(ExitCode::from(code.clamp(0, 255) as u8))
}
