//! One shard of a job whose home is a bucket, processed by a worker that shares nothing with
//! the others but the bucket: take the shard's lease in the bucket, bring its checkpoints
//! into the worker's scratch copy of the job, process it there exactly as on disk (items in
//! the supervised item worker, each journalled locally) while checkpoints go up, then upload
//! the shard and create its record ([`crate::commit`]).

use crate::checkpoint::{pull_checkpoints, Checkpoints};
use crate::commit::push;
use crate::integrity::{finished, Finished};
use crate::keys;
use crate::lease::{acquire, Acquired, BucketLease};
use anyhow::{Context, Result};
use sparc3d_schema::CompletionRecord;
use sparc3d_sources::objects::Prefix;
use sparc3d_workers::lease::{file_token, owner_name};
use sparc3d_workers::shard::events::Event;
use sparc3d_workers::shard::{busy, committed_outcome, skipped, CONTENDERS};
use sparc3d_workers::{process_shard, Job, ShardOutcome, WorkOptions};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Processes shard `shard` of the bucket job at `prefix`, whose scratch copy is `job`;
/// `every` is the time between checkpoints.
pub fn work_shard(
    prefix: &Prefix<'static>,
    job: &Job,
    shard: u64,
    opts: &mut WorkOptions,
    every: Duration,
) -> Result<ShardOutcome> {
    // A damaged record is moved aside under the lease (below), never outside it.
    if let Finished::Done(r) = finished(prefix, shard)? {
        skipped(opts, shard, "already done");
        return Ok(ShardOutcome::AlreadyDone(*r));
    }
    // This shard's slice of the frozen manifest and its index page, nothing more of it.
    crate::scratch::pull_slices(prefix, job, &[shard])?;
    let owner = owner_name();
    let shard_stop = Arc::new(AtomicBool::new(false));
    let held = match acquire(
        prefix,
        shard,
        &owner,
        opts.lease_ttl_s,
        Arc::clone(&shard_stop),
    )? {
        Acquired::Held(l) => Arc::new(l),
        Acquired::Busy(h) => return Ok(busy(opts, shard, h.owner)),
        Acquired::Contended => return Ok(busy(opts, shard, CONTENDERS.into())),
    };
    let leased = Leased {
        prefix,
        job,
        shard,
        writer: file_token(&owner),
        held: Arc::clone(&held),
        shard_stop,
    };
    let result = leased.work(opts, every);
    drop(leased);
    if let Ok(lease) = Arc::try_unwrap(held) {
        lease.release();
    }
    result
}

/// A shard whose bucket lease this worker holds.
struct Leased<'a> {
    prefix: &'a Prefix<'static>,
    job: &'a Job,
    shard: u64,
    /// This holder's name in its uploads and checkpoints.
    writer: String,
    held: Arc<BucketLease>,
    /// Stops the item loop: set on the loss of the lease, or copied from the user's stop.
    shard_stop: Arc<AtomicBool>,
}

impl Leased<'_> {
    /// Processes the shard in the scratch copy and pushes it to the bucket.
    fn work(&self, opts: &mut WorkOptions, every: Duration) -> Result<ShardOutcome> {
        // Finished between our look and our lease, or finished but damaged.
        match finished(self.prefix, self.shard)? {
            Finished::No => {}
            Finished::Done(r) => return Ok(ShardOutcome::AlreadyDone(*r)),
            Finished::Damaged(why) => self.set_aside(opts, &why)?,
        }
        pull_checkpoints(self.prefix, self.job, self.shard)?;
        let checkpoints = Arc::new(Mutex::new(Checkpoints::new(
            self.prefix,
            self.shard,
            &self.writer,
            Arc::clone(&self.held),
            every,
        )));
        let outcome = self.run_items(opts, &checkpoints);
        match outcome {
            Ok(ShardOutcome::Done(r)) | Ok(ShardOutcome::AlreadyDone(r)) => self.push(opts, &r),
            other => self.stopped(opts, other, &checkpoints),
        }
    }

    /// Moves the shard, whose record's object is missing, of another size or replaced, aside
    /// in the bucket ([`crate::quarantine`]), so that it is converted again here.
    fn set_aside(&self, opts: &mut WorkOptions, why: &str) -> Result<()> {
        let shard = self.shard;
        self.held
            .confirm()
            .map_err(|lost| anyhow::anyhow!("shard {shard}: not moved aside: {lost}"))?;
        let moved_to = crate::quarantine::quarantine(self.prefix, shard, why)?;
        (opts.events)(Event::ShardDamaged {
            shard,
            reason: why.to_string(),
            moved_to: moved_to.unwrap_or_default(),
        });
        Ok(())
    }

    /// The item loop of `sparc3d_workers` in the scratch copy, checkpointing after items and
    /// stopping on the user's stop or the loss of the bucket lease.
    fn run_items(
        &self,
        opts: &mut WorkOptions,
        checkpoints: &Arc<Mutex<Checkpoints>>,
    ) -> Result<ShardOutcome> {
        let hook = Arc::clone(checkpoints);
        opts.after_item = Some(Box::new(move |j| match hook.lock() {
            Ok(mut c) => c.after_item(j, false),
            Err(_) => Ok(()),
        }));
        let user_stop = std::mem::replace(&mut opts.stop, Arc::clone(&self.shard_stop));
        let forward = forward_stop(Arc::clone(&user_stop), Arc::clone(&self.shard_stop));
        let outcome = process_shard(self.job, self.shard, opts);
        opts.stop = user_stop;
        opts.after_item = None;
        self.shard_stop.store(true, Ordering::SeqCst);
        let _ = forward.join();
        Ok(outcome?)
    }

    /// The loop ended before the shard was written: a lost lease is said; otherwise what
    /// finished goes up as a last checkpoint for the next holder.
    fn stopped(
        &self,
        opts: &mut WorkOptions,
        outcome: Result<ShardOutcome>,
        checkpoints: &Mutex<Checkpoints>,
    ) -> Result<ShardOutcome> {
        if let Some(why) = self.held.lost() {
            let message = format!(
                "shard {}: this worker lost its lease {}: {why}; it stops here and leaves the \
                 shard to whichever worker takes it next",
                self.shard,
                self.prefix.url(&keys::lease(self.shard))
            );
            (opts.events)(Event::LeaseLost {
                shard: self.shard,
                message: message.clone(),
            });
            return Ok(ShardOutcome::LeaseLost(message));
        }
        // The shard's own error is the one to report (the checkpoint may fail for the same
        // cause).
        let last = match checkpoints.lock() {
            Ok(mut c) => c.last(),
            Err(_) => Ok(()),
        };
        let outcome = outcome?;
        last.with_context(|| format!("shard {}: the last checkpoint", self.shard))?;
        Ok(outcome)
    }

    /// Uploads the shard written in the scratch copy and creates its record.
    fn push(&self, opts: &mut WorkOptions, record: &CompletionRecord) -> Result<ShardOutcome> {
        let shard = self.shard;
        (opts.events)(Event::ShardWriting { shard });
        let layout = &self.job.layout;
        let pushed = push(self.prefix, layout, shard, record, &self.writer, &self.held)?;
        // The bucket has it now: the scratch copy goes.
        let _ = std::fs::remove_file(layout.shard_file(shard));
        let _ = std::fs::remove_file(layout.completion(shard));
        Ok(committed_outcome(opts, shard, pushed))
    }
}

/// Copies the user's stop into the shard's stop flag until the shard's is set.
fn forward_stop(user: Arc<AtomicBool>, shard: Arc<AtomicBool>) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        while !shard.load(Ordering::SeqCst) {
            if user.load(Ordering::SeqCst) {
                shard.store(true, Ordering::SeqCst);
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    })
}
