//! `sparc3d retry JOB [--class C]`: queues failed items (of one class, or all) to be converted
//! again. A finished shard keeps its other rows in a fresh journal and loses its completion
//! record and file, so the next `run` or `work` converts only the retried items and writes it
//! again. A job in a bucket is read in a local view (records, leases, checkpoints and the
//! finished shards), and the change is made in the bucket (`sparc3d_bucket::retry`).

use anyhow::{bail, Result};
use sparc3d_schema::{ErrorClass, ItemStatus, ShardRow};
use sparc3d_workers::store::read::read_rows;
use sparc3d_workers::store::state::{shard_state, Check, ShardState};
use sparc3d_workers::Job;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d retry`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder, or the bucket prefix that is the job's home.
    pub job: PathBuf,
    /// Only failures of this class (e.g. timeout, out_of_memory, crashed).
    #[arg(long)]
    pub class: Option<String>,
}

/// Runs `sparc3d retry`.
pub fn run(args: Args) -> Result<ExitCode> {
    let (dir, bucket) = match sparc3d_bucket::JobHome::parse(&args.job)? {
        sparc3d_bucket::JobHome::Folder(dir) => (dir, None),
        sparc3d_bucket::JobHome::Bucket(url) => (
            crate::job::bucket_home::retry_view(&url)?,
            Some(crate::job::bucket_home::prefix(&url)?),
        ),
    };
    let job = Job::open_checked(&dir)?;
    let class = args.class.as_deref().map(ErrorClass::parse).transpose()?;
    let matches = |r: &ShardRow| {
        r.status == ItemStatus::Failed && (class.is_none() || r.error_class == class)
    };
    let (mut queued, mut shards) = (0usize, 0usize);
    for shard in 0..job.file.shards {
        let rows = match shard_state(&job.layout, shard, job.fingerprint(), Check::Quick)? {
            ShardState::Done(_) => read_rows(&job.layout.shard_file(shard))?,
            ShardState::Damaged(why) => {
                return Err(sparc3d_workers::store::read::damaged(&job, shard, &why).into())
            }
            ShardState::Running(l) => {
                if sparc3d_workers::store::read::shard_rows(&job, shard, Check::Quick)?
                    .iter()
                    .any(matches)
                {
                    bail!(
                        "shard {shard} is being processed by {}; retry when it is finished",
                        l.owner
                    );
                }
                continue;
            }
            ShardState::Pending => {
                sparc3d_workers::store::read::shard_rows(&job, shard, Check::Quick)?
            }
        };
        let n = rows.iter().filter(|r| matches(r)).count();
        if n == 0 {
            continue;
        }
        let kept: Vec<ShardRow> = rows.into_iter().filter(|r| !matches(r)).collect();
        if let Some(prefix) = &bucket {
            sparc3d_bucket::retry::requeue(prefix, shard, job.fingerprint(), &kept)?;
            queued += n;
            shards += 1;
            continue;
        }
        // The journal first, then the completion record goes, then the shard file (its rows
        // are in the journal): a crash in between leaves the shard done, or a file without
        // its record that the next writer replaces, and retry can simply run again.
        sparc3d_workers::journal::set::replace_with_rows(
            &job.layout,
            shard,
            job.fingerprint(),
            &kept,
        )?;
        for file in [job.layout.completion(shard), job.layout.shard_file(shard)] {
            match std::fs::remove_file(&file) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => return Err(sparc3d_workers::WorkerError::io("removing", &file, e).into()),
            }
        }
        queued += n;
        shards += 1;
    }
    eprintln!("{queued} failed items in {shards} shards queued; `sparc3d run` converts them again");
    Ok(ExitCode::SUCCESS)
}
