//! The `sparc3d` command line: parses arguments and hands each subcommand to `commands/`.

mod cluster;
mod colours;
mod commands;
mod export_name;
mod flags;
mod hints;
mod huge_pages;
mod item_lookup;
mod job;
mod lane_plan;
mod local_workers;
mod machine;
mod memory;
mod near_duplicates;
mod pictures;
mod pool;
mod progress;
mod row_filter;
mod sample;
mod signals;
mod stats;
mod stuck;
mod summary;
mod units;
mod validation;

use clap::Parser;

#[global_allocator]
static ALLOCATOR: huge_pages::HugePageAlloc = huge_pages::HugePageAlloc;

/// Lets a closed pipe (`sparc3d inspect JOB | head`) end the process quietly, as it does for
/// other command-line tools, instead of a panic in `println!`.
fn restore_default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: resetting a signal disposition to its default before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// An error and its causes on one line, leaving out a cause whose text the line already
/// holds (typed errors often print their source inside their own message).
fn describe(err: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in err.chain() {
        let text = cause.to_string();
        if line.contains(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line
}

fn main() -> std::process::ExitCode {
    huge_pages::configure_from_env();
    restore_default_sigpipe();
    let cli = commands::Cli::parse();
    match commands::run(cli) {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {}", describe(&err));
            std::process::ExitCode::FAILURE
        }
    }
}
