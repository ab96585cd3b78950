//! The `sparc3d` command line: parses arguments and hands each subcommand to `commands/`.

mod cluster;
mod commands;
mod manifest_io;
mod npz;
mod progress;
mod sample;
mod shard_io;
mod summary;
mod units;

use clap::Parser;

/// Lets a closed pipe (`sparc3d inspect JOB | head`) end the process quietly, as it does for
/// other command-line tools, instead of a panic in `println!`.
fn restore_default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: resetting a signal disposition to its default before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() -> std::process::ExitCode {
    restore_default_sigpipe();
    let cli = commands::Cli::parse();
    match commands::run(cli) {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {err:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
