//! `sparc3d status JOB [--json]`: shards done/running/pending, items ok/failed/pending,
//! throughput, ETA, the slowest items in flight and the top error classes.

use crate::rows::summary::{summarize, RATE_MIN_ITEMS, RATE_MIN_SECONDS};
use crate::util::units::format_seconds;
use anyhow::Result;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d status`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder, or the bucket prefix that is the job's home.
    pub job: PathBuf,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `sparc3d status`.
pub fn run(args: Args) -> Result<ExitCode> {
    let s = match sparc3d_bucket::JobHome::parse(&args.job)? {
        sparc3d_bucket::JobHome::Folder(dir) => {
            summarize(&crate::job::setup::open_read_only(&dir)?)?
        }
        sparc3d_bucket::JobHome::Bucket(url) => crate::job::bucket_home::summarize(&url)?,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
        return Ok(ExitCode::SUCCESS);
    }
    println!(
        "shards: {} done, {} running, {} pending{} (of {})",
        s.shards_done,
        s.shards_running,
        s.shards_pending,
        if s.shards_damaged > 0 {
            format!(", {} damaged", s.shards_damaged)
        } else {
            String::new()
        },
        s.shards
    );
    println!(
        "items:  {} ok, {} failed, {} pending (of {})",
        s.ok, s.failed, s.pending, s.items
    );
    match (s.items_per_hour, s.eta_seconds) {
        (Some(r), Some(eta)) if s.pending > 0 => {
            println!("rate:   {r:.0} items/hour, ETA {}", format_seconds(eta))
        }
        (Some(r), _) => println!("rate:   {r:.0} items/hour"),
        (None, _) if s.pending > 0 && s.ok + s.failed > 0 => println!(
            "rate:   not known yet (after {RATE_MIN_ITEMS} items and {RATE_MIN_SECONDS} s)"
        ),
        _ => {}
    }
    if !s.in_flight.is_empty() {
        println!("in flight (slowest first):");
        for f in s.in_flight.iter().take(5) {
            println!(
                "  {:>8}  shard {:>5}  {}",
                format_seconds(f.seconds),
                f.shard,
                f.uri
            );
        }
    }
    if !s.error_classes.is_empty() {
        let mut classes: Vec<_> = s.error_classes.iter().collect();
        classes.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
        println!("errors:");
        for (c, n) in classes.iter().take(8) {
            println!("  {n:>6}  {c}");
        }
    }
    if let Some(hint) = crate::util::hints::failures(&args.job, s.failed) {
        println!("{hint}");
    }
    for d in &s.damaged {
        println!(
            "damaged: shard {}: {}; `sparc3d run` moves it aside and converts it again",
            d.shard, d.reason
        );
    }
    // Cluster runs: Slurm arrays submitted by `sparc3d submit slurm` (nothing if none).
    crate::cluster::slurm::print_status(&args.job);
    Ok(ExitCode::SUCCESS)
}
