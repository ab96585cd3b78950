//! `sparc3d verify JOB [--dry-run] [--json]`: hashes every finished shard against its
//! completion record, moves damaged shards aside (into `JOB/quarantine/`, nothing is deleted)
//! so that the next `run` converts them again, and says which they are. Exits 1 when any
//! shard was damaged. A job in a bucket is hashed in its local view (downloaded), and its
//! damaged shards are moved aside in the bucket (`sparc3d_bucket::quarantine`).

use anyhow::Result;
use rayon::prelude::*;
use serde::Serialize;
use sparc3d_workers::store::state::{verify_shard, Verified};
use sparc3d_workers::Job;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `sparc3d verify`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder, or the bucket prefix that is the job's home (read through a local copy).
    pub job: PathBuf,
    /// Only report: leave damaged shards where they are.
    #[arg(long)]
    pub dry_run: bool,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// One shard's result, as printed.
#[derive(Debug, Serialize)]
struct ShardReport {
    shard: u64,
    /// `good`, `damaged`, `busy` (damaged or re-stamped, but leased by a live worker).
    state: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    reason: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    moved_to: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    items: Option<u64>,
}

impl ShardReport {
    fn new(shard: u64) -> Self {
        Self {
            shard,
            state: "good",
            reason: None,
            moved_to: None,
            items: None,
        }
    }
}

#[derive(Debug, Serialize)]
struct Report {
    shards: u64,
    finished: u64,
    good: u64,
    damaged: u64,
    busy: u64,
    restamped: u64,
    bytes_hashed: u64,
    seconds: f64,
    problems: Vec<ShardReport>,
}

/// Runs `sparc3d verify`.
pub fn run(mut args: Args) -> Result<ExitCode> {
    // In a bucket, the local view is checked, and damaged shards are moved aside in the
    // bucket itself.
    let name = args.job.display().to_string();
    let home = sparc3d_bucket::JobHome::parse(&args.job)?;
    args.job = crate::bucket_home::local_view(&args.job)?;
    let job = Job::open(&args.job)?;
    let in_bucket = matches!(home, sparc3d_bucket::JobHome::Bucket(_));
    let mut report = verify_job(&job, !args.dry_run && !in_bucket)?;
    if let (sparc3d_bucket::JobHome::Bucket(url), false) = (&home, args.dry_run) {
        let prefix = crate::bucket_home::prefix(url)?;
        for p in report.problems.iter_mut().filter(|p| p.state == "damaged") {
            let reason = p.reason.clone().unwrap_or_default();
            p.moved_to = sparc3d_bucket::quarantine::quarantine(&prefix, p.shard, &reason)?;
        }
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_text(&report, &name);
    }
    Ok(if report.damaged > 0 {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}

/// Hashes every finished shard of `job` against its completion record (in parallel) and
/// tallies the results; with `move_damaged`, damaged shards are moved into quarantine.
fn verify_job(job: &Job, move_damaged: bool) -> Result<Report> {
    let start = Instant::now();
    let results: Vec<(u64, Verified)> = (0..job.file.shards)
        .into_par_iter()
        .map(|shard| {
            let v = verify_shard(&job.layout, shard, job.fingerprint(), move_damaged)?;
            Ok((shard, v))
        })
        .collect::<Result<_>>()?;
    let mut r = Report {
        shards: job.file.shards,
        finished: 0,
        good: 0,
        damaged: 0,
        busy: 0,
        restamped: 0,
        bytes_hashed: 0,
        seconds: 0.0,
        problems: Vec::new(),
    };
    let items_of = |shard: u64| job.items.iter().filter(|i| i.shard == shard).count() as u64;
    for (shard, v) in results {
        match v {
            Verified::NotFinished => {}
            Verified::Good { record, restamped } => {
                r.finished += 1;
                r.good += 1;
                r.bytes_hashed += record.bytes;
                r.restamped += restamped as u64;
            }
            Verified::Damaged { reason, moved_to } => {
                r.finished += 1;
                r.damaged += 1;
                r.problems.push(ShardReport {
                    shard,
                    state: "damaged",
                    reason: Some(reason),
                    moved_to: moved_to.map(|p| p.display().to_string()),
                    items: Some(items_of(shard)),
                });
            }
            Verified::Busy { reason, owner } => {
                r.finished += 1;
                r.busy += 1;
                r.problems.push(ShardReport {
                    state: "busy",
                    reason: Some(format!("{reason}; leased by {owner}, left alone")),
                    ..ShardReport::new(shard)
                });
            }
        }
    }
    r.seconds = start.elapsed().as_secs_f64();
    Ok(r)
}

/// Prints one line per damaged or busy shard, with what to run next, and the tally.
fn print_text(r: &Report, root: &str) {
    for p in &r.problems {
        let reason = p.reason.as_deref().unwrap_or_default();
        match (&p.moved_to, p.state) {
            (Some(to), _) => println!(
                "shard {}: damaged: {reason}; moved aside to {to}; `sparc3d run {root}` \
                 converts its {} items again",
                p.shard,
                p.items.unwrap_or(0)
            ),
            (None, "damaged") => println!(
                "shard {}: damaged: {reason}; `sparc3d verify {root}` (without --dry-run) \
                 moves it aside and `sparc3d run {root}` converts its {} items again",
                p.shard,
                p.items.unwrap_or(0)
            ),
            _ => println!("shard {}: {reason}", p.shard),
        }
    }
    let restamped = if r.restamped > 0 {
        format!(
            " ({} touched but unchanged: stamps re-recorded)",
            r.restamped
        )
    } else {
        String::new()
    };
    println!(
        "{} of {} shards finished: {} good, {} damaged, {} busy; {:.1} MB hashed in {:.2} s{restamped}",
        r.finished,
        r.shards,
        r.good,
        r.damaged,
        r.busy,
        r.bytes_hashed as f64 / 1e6,
        r.seconds,
    );
}
