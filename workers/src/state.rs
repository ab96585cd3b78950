//! Whether a shard is done (a valid completion record), running (a live lease) or pending.

use crate::error::{Result, WorkerError};
use crate::fsutil::read_json;
use crate::lease::{self, LeaseInfo};
use sparc3d_schema::{CompletionRecord, JobLayout};

/// The state of one shard.
#[derive(Debug, Clone, PartialEq)]
pub enum ShardState {
    /// Finished: its completion record.
    Done(CompletionRecord),
    /// A live worker holds its lease.
    Running(LeaseInfo),
    /// Not finished and not held (it may have a journal of finished items).
    Pending,
}

/// The completion record of a shard if the shard is finished: the record parses, its shard
/// file exists with the recorded size. A record with another fingerprint is an error.
pub fn completion(
    layout: &JobLayout,
    shard: u64,
    fingerprint: &str,
) -> Result<Option<CompletionRecord>> {
    let path = layout.completion(shard);
    if !path.exists() {
        return Ok(None);
    }
    let record: CompletionRecord = read_json(&path)?;
    if record.fingerprint != fingerprint {
        return Err(WorkerError::ConfigDrift {
            what: format!("shard {}", layout.shard_file(shard).display()),
            found: record.fingerprint,
            expected: fingerprint.to_string(),
        });
    }
    let size = std::fs::metadata(layout.shard_file(shard))
        .map(|m| m.len())
        .ok();
    Ok((size == Some(record.bytes)).then_some(record))
}

/// The state of a shard.
pub fn shard_state(layout: &JobLayout, shard: u64, fingerprint: &str) -> Result<ShardState> {
    if let Some(r) = completion(layout, shard, fingerprint)? {
        return Ok(ShardState::Done(r));
    }
    match lease::read(&layout.lease(shard)) {
        Some(l) if !l.is_stale(crate::now()) => Ok(ShardState::Running(l)),
        _ => Ok(ShardState::Pending),
    }
}
