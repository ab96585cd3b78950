//! The loop over one shard: claim its lease, resume from its journals, run each unfinished
//! item in the supervised item worker, journal the outcome in this holder's own journal, write
//! each row into the shard file once the items before it are finished, and commit the shard
//! when every item is. Every journal append and the shard's commit
//! are preceded by a check that the lease is still held; a worker that lost it (stopped past
//! it, or taken over) stops with [`ShardOutcome::LeaseLost`].

pub mod events;
mod item_loop;
pub mod lanes;

use crate::error::{Result, WorkerError};
use crate::job::Job;
use crate::journal::{self, Journal};
use crate::lease::{self, Acquired, Lease};
use crate::shard::events::Event;
use crate::shard::item_loop::{fence, run_items, LoopEnd, ShardWork};
use crate::store::commit::Committed;
use crate::store::state::{self, Check, Completion};
use crate::store::write::ShardStream;
use crate::work_options::WorkOptions;
use sparc3d_schema::CompletionRecord;

/// What happened to a shard.
#[derive(Debug, Clone, PartialEq)]
pub enum ShardOutcome {
    /// Written now.
    Done(CompletionRecord),
    /// Already finished before; its completion record.
    AlreadyDone(CompletionRecord),
    /// Another live worker holds its lease.
    Busy(String),
    /// Stopped on request; the journal keeps what finished.
    Stopped,
    /// This worker lost the shard's lease and left the shard to its new holder; the message
    /// names the lease and what happened.
    LeaseLost(String),
}

/// Processes shard `shard` of `job`. A finished shard is checked against its completion
/// record ([`Check::Quick`]) before it is skipped; a damaged one is moved aside and converted
/// again. Item failures become rows; errors are failures of the job's machinery (files,
/// leases, config drift) and leave the journals for a later resume. A worker that lost the
/// lease stops with [`ShardOutcome::LeaseLost`].
pub fn process_shard(job: &Job, shard: u64, opts: &mut WorkOptions) -> Result<ShardOutcome> {
    let layout = &job.layout;
    let fp = job.fingerprint().to_string();
    if let Completion::Done(r) = state::completion(layout, shard, &fp, Check::Quick)? {
        clear_leftovers(job, shard, opts.lease_ttl_s)?;
        skipped(opts, shard, "already done");
        return Ok(ShardOutcome::AlreadyDone(*r));
    }
    crate::fsutil::create_dir(&layout.state_dir())?;
    crate::fsutil::create_dir(&layout.shards_dir())?;
    let owner = lease::owner_name();
    let held = match lease::acquire(&layout.lease(shard), &owner, opts.lease_ttl_s)? {
        Acquired::Held(l) => l,
        Acquired::Busy(holder) => return Ok(busy(opts, shard, holder.owner)),
        Acquired::Contended => return Ok(busy(opts, shard, CONTENDERS.into())),
    };
    let result = run_leased(job, shard, opts, &held, &owner);
    held.release();
    match result {
        Err(lost @ WorkerError::LeaseLost { .. }) => {
            let message = lost.to_string();
            (opts.events)(Event::LeaseLost {
                shard,
                message: message.clone(),
            });
            Ok(ShardOutcome::LeaseLost(message))
        }
        other => other,
    }
}

/// A worker killed after writing a shard's completion record but before removing its
/// journals and lease leaves them behind (so may a stopped former holder that was continued
/// after the shard was written). The shard holds every row, so the journals are redundant:
/// take the lease (unless a live worker still holds it, which then cleans up itself), remove
/// the journals, release the lease.
pub fn clear_leftovers(job: &Job, shard: u64, lease_ttl_s: f64) -> Result<()> {
    let layout = &job.layout;
    let lease_file = layout.lease(shard);
    if !journal::set::exists(layout, shard) && !lease_file.exists() {
        return Ok(());
    }
    if let Acquired::Held(held) = lease::acquire(&lease_file, &lease::owner_name(), lease_ttl_s)? {
        let removed = journal::set::remove_all(layout, shard);
        held.release();
        removed?;
    }
    Ok(())
}

fn run_leased(
    job: &Job,
    shard: u64,
    opts: &mut WorkOptions,
    held: &Lease,
    owner: &str,
) -> Result<ShardOutcome> {
    let layout = &job.layout;
    let fp = job.fingerprint().to_string();
    // Someone may have finished it between our check and our lease; a damaged shard is
    // moved aside (under the lease, so no one else moves or writes it meanwhile).
    match state::completion(layout, shard, &fp, Check::Quick)? {
        Completion::Done(r) => return Ok(ShardOutcome::AlreadyDone(*r)),
        Completion::Damaged(reason) => {
            fence(held, shard)?;
            let moved_to = state::quarantine(layout, shard, &reason)?;
            (opts.events)(Event::ShardDamaged {
                shard,
                reason,
                moved_to: moved_to.display().to_string(),
            });
        }
        Completion::Absent => {}
    }
    let items = job.shard_items(shard)?;
    // What the earlier holders journalled, read once: this holder writes its own file.
    let earlier = journal::set::read(layout, shard, Some(&fp))?;
    let writer = lease::file_token(owner);
    let own = layout.holder_journal(shard, &writer);
    let mut journal = Journal::create(&own, shard, &fp, earlier)?;
    let started_at = journal.state.created_at.unwrap_or_else(crate::clock::now);
    (opts.events)(Event::ShardStarted {
        shard,
        items: items.len() as u64,
        done: journal.state.done.len() as u64,
    });
    // Rows go into the shard file as their items finish in order ([`ShardStream`]): the
    // earlier holders' now, this holder's as the loop journals them.
    let mut stream = ShardStream::create(job, shard, &writer)?;
    stream.catch_up(&journal)?;
    let mut work = ShardWork {
        shard,
        held,
        config: &job.file.config,
        opts,
        stream: &mut stream,
    };
    if let LoopEnd::Stopped = run_items(&mut work, &mut journal, &items)? {
        return Ok(ShardOutcome::Stopped);
    }
    (opts.events)(Event::ShardWriting { shard });
    // A failed background flush of the journal is reported before the shard is put in place;
    // the flush still running is not waited for: once the shard is committed, the journals go.
    journal.check()?;
    let fenced = || fence(held, shard);
    let committed = stream.finish(job, shard, started_at, &fenced)?;
    journal.abandon();
    // The shard holds every row now: the journals (this holder's and the earlier ones') go.
    let _ = journal::set::remove_all(layout, shard);
    Ok(committed_outcome(opts, shard, committed))
}

/// What the commit of shard `shard` (on disk, or to a bucket) comes to, told to
/// `opts.events`: this worker's shard finished ([`Event::ShardFinished`]), or another
/// worker's finished first and is kept ([`Event::ShardSkipped`]).
pub fn committed_outcome(opts: &mut WorkOptions, shard: u64, committed: Committed) -> ShardOutcome {
    match committed {
        Committed::Done(record) => {
            (opts.events)(Event::ShardFinished {
                shard,
                rows: record.rows,
                ok: record.ok,
                failed: record.failed,
            });
            ShardOutcome::Done(record)
        }
        Committed::FinishedElsewhere(record) => {
            let why = "finished by another worker meanwhile; its shard is kept";
            skipped(opts, shard, why);
            ShardOutcome::AlreadyDone(record)
        }
    }
}

/// Who holds a shard's lease when several workers take it at once (none of them got it).
pub const CONTENDERS: &str = "several workers taking its lease at once";

/// Shard `shard` left to `holder`, who holds its lease (or [`CONTENDERS`]): told to
/// `opts.events`, and the outcome that says so.
pub fn busy(opts: &mut WorkOptions, shard: u64, holder: String) -> ShardOutcome {
    skipped(opts, shard, &format!("leased by {holder}"));
    ShardOutcome::Busy(holder)
}

/// Tells `opts.events` that shard `shard` is not processed, and why ([`Event::ShardSkipped`]).
pub fn skipped(opts: &mut WorkOptions, shard: u64, reason: &str) {
    (opts.events)(Event::ShardSkipped {
        shard,
        reason: reason.into(),
    });
}
