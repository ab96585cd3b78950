//! `sparc3d verify JOB [--dry-run] [--json]`: hashes every finished shard against its
//! completion record, moves damaged shards aside (into `JOB/quarantine/`, nothing is deleted)
//! so that the next `run` converts them again, and says which they are. Exits 1 when any
//! shard was damaged. In a job in a bucket, every finished shard's object is read from the
//! bucket and hashed, whatever local copy there is, and damaged shards (a missing object
//! included) are moved aside in the bucket (`sparc3d_bucket::verify`).

use anyhow::Result;
use rayon::prelude::*;
use serde::Serialize;
use sparc3d_bucket::verify::{verify_shard as verify_in_bucket, Verified as InBucket};
use sparc3d_workers::store::state::{verify_shard, Verified};
use sparc3d_workers::Job;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `sparc3d verify`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder, or the bucket prefix that is the job's home (its objects read from the
    /// bucket).
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
pub fn run(args: Args) -> Result<ExitCode> {
    let name = args.job.display().to_string();
    let (report, in_bucket) = match sparc3d_bucket::JobHome::parse(&args.job)? {
        sparc3d_bucket::JobHome::Folder(dir) => {
            (verify_job(&Job::open_checked(&dir)?, !args.dry_run)?, false)
        }
        sparc3d_bucket::JobHome::Bucket(url) => (verify_bucket(&url, !args.dry_run)?, true),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_text(&report, &name, in_bucket);
    }
    Ok(if report.damaged > 0 {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}

/// One shard's result, on disk or in a bucket.
enum Found {
    NotFinished,
    /// Good: its bytes, and whether its stamp (its ETag in a bucket) was re-recorded.
    Good {
        bytes: u64,
        restamped: bool,
    },
    Damaged {
        reason: String,
        moved_to: Option<String>,
    },
    /// Left alone; why.
    Busy {
        reason: String,
    },
}

impl From<Verified> for Found {
    fn from(v: Verified) -> Self {
        match v {
            Verified::NotFinished => Found::NotFinished,
            Verified::Good { record, restamped } => Found::Good {
                bytes: record.bytes,
                restamped,
            },
            Verified::Damaged { reason, moved_to } => Found::Damaged {
                reason,
                moved_to: moved_to.map(|p| p.display().to_string()),
            },
            Verified::Busy { reason, owner } => Found::Busy {
                reason: format!("{reason}; leased by {owner}, left alone"),
            },
        }
    }
}

impl From<InBucket> for Found {
    fn from(v: InBucket) -> Self {
        match v {
            InBucket::NotFinished => Found::NotFinished,
            InBucket::Good { record, rerecorded } => Found::Good {
                bytes: record.bytes,
                restamped: rerecorded,
            },
            InBucket::Damaged { reason, moved_to } => Found::Damaged { reason, moved_to },
            InBucket::Busy { reason } => Found::Busy { reason },
        }
    }
}

/// Hashes every finished shard of `job` against its completion record (in parallel) and
/// tallies the results; with `move_damaged`, damaged shards are moved into quarantine.
fn verify_job(job: &Job, move_damaged: bool) -> Result<Report> {
    let start = Instant::now();
    let results: Vec<(u64, Found)> = (0..job.file.shards)
        .into_par_iter()
        .map(|shard| {
            let v = verify_shard(&job.layout, shard, job.fingerprint(), move_damaged)?;
            Ok((shard, v.into()))
        })
        .collect::<Result<_>>()?;
    Ok(tally(job, results, start))
}

/// [`verify_job`] for the job in the bucket at `url`: every finished shard's object read from
/// the bucket and hashed (never the local copy), damaged ones moved aside in the bucket.
fn verify_bucket(url: &sparc3d_sources::RemoteUrl, move_damaged: bool) -> Result<Report> {
    let start = Instant::now();
    let prefix = crate::job::bucket_home::prefix(url)?;
    let (job, _) = crate::job::bucket_home::view_job(url, &prefix)?;
    let results: Vec<(u64, Found)> = (0..job.file.shards)
        .into_par_iter()
        .map(|shard| {
            let v = verify_in_bucket(&prefix, shard, job.fingerprint(), move_damaged)?;
            Ok((shard, v.into()))
        })
        .collect::<Result<_>>()?;
    Ok(tally(&job, results, start))
}

/// The report of `results`, one per shard of `job`, found since `start`.
fn tally(job: &Job, results: Vec<(u64, Found)>, start: Instant) -> Report {
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
    let items_of = |shard: u64| job.shard_items(shard).map_or(0, |items| items.len() as u64);
    for (shard, found) in results {
        r.finished += !matches!(found, Found::NotFinished) as u64;
        match found {
            Found::NotFinished => {}
            Found::Good { bytes, restamped } => {
                r.good += 1;
                r.bytes_hashed += bytes;
                r.restamped += restamped as u64;
            }
            Found::Damaged { reason, moved_to } => {
                r.damaged += 1;
                r.problems.push(ShardReport {
                    state: "damaged",
                    reason: Some(reason),
                    moved_to,
                    items: Some(items_of(shard)),
                    ..ShardReport::new(shard)
                });
            }
            Found::Busy { reason } => {
                r.busy += 1;
                r.problems.push(ShardReport {
                    state: "busy",
                    reason: Some(reason),
                    ..ShardReport::new(shard)
                });
            }
        }
    }
    r.seconds = start.elapsed().as_secs_f64();
    r
}

/// Prints one line per damaged or busy shard, with what to run next, and the tally.
fn print_text(r: &Report, root: &str, in_bucket: bool) {
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
    let restamped = match (r.restamped, in_bucket) {
        (0, _) => String::new(),
        (n, false) => format!(" ({n} touched but unchanged: stamps re-recorded)"),
        (n, true) => {
            format!(" ({n} objects unchanged under a new or unrecorded ETag: ETags recorded)")
        }
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
