//! The `sparc3d` command line: parses arguments and hands each subcommand to `commands/`.

mod commands;
mod manifest_io;
mod progress;
mod shard_io;
mod summary;
mod units;

use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = commands::Cli::parse();
    match commands::run(cli) {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {err:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
