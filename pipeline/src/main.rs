//! The `sparc3d` command line: parses arguments and hands each subcommand to `commands/`.

mod check;
mod cluster;
mod commands;
mod flags;
mod job;
mod rows;
mod run;
mod util;

use clap::Parser;

#[global_allocator]
static ALLOCATOR: util::huge_pages::HugePageAlloc = util::huge_pages::HugePageAlloc;

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
    util::huge_pages::configure_from_env();
    restore_default_sigpipe();
    let cli = commands::Cli::parse();
    match commands::run(cli) {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {}", util::error_line::describe(&err));
            std::process::ExitCode::FAILURE
        }
    }
}
