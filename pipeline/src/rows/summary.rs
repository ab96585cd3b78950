//! A job's progress read from its folder: completion records (checked against their shard
//! files), leases and journals (every holder's of a shard, read together). Used by `status` and by `run` (to plan, and to start its
//! counters where the last run stopped).

use anyhow::Result;
use rayon::prelude::*;
use serde::Serialize;
use sparc3d_schema::ItemStatus;
use sparc3d_workers::store::state::{shard_state, Check, ShardState};
use sparc3d_workers::Job;
use std::collections::BTreeMap;

/// A finished shard that no longer matches its completion record.
#[derive(Debug, Clone, Serialize)]
pub struct DamagedShard {
    /// Shard index.
    pub shard: u64,
    /// What is wrong.
    pub reason: String,
}

/// An item being converted right now.
#[derive(Debug, Clone, Serialize)]
pub struct InFlight {
    /// Shard.
    pub shard: u64,
    /// Item id.
    pub id: String,
    /// Source path.
    pub uri: String,
    /// Seconds since it started.
    pub seconds: f64,
}

/// Progress of a job.
#[derive(Debug, Clone, Default, Serialize)]
pub struct JobSummary {
    /// Shards in the job.
    pub shards: u64,
    /// Shards finished.
    pub shards_done: u64,
    /// Shards leased by a live worker.
    pub shards_running: u64,
    /// Shards neither.
    pub shards_pending: u64,
    /// Shards finished once whose file no longer matches its record (converted again by the
    /// next `run` or `work`).
    pub shards_damaged: u64,
    /// Those shards and why.
    pub damaged: Vec<DamagedShard>,
    /// Items in the job.
    pub items: u64,
    /// Items finished ok.
    pub ok: u64,
    /// Items finished failed.
    pub failed: u64,
    /// Items not finished.
    pub pending: u64,
    /// Failed items per class.
    pub error_classes: BTreeMap<String, u64>,
    /// Items in flight, slowest first.
    pub in_flight: Vec<InFlight>,
    /// Items finished per hour since the job's first item started (`None` until
    /// [`RATE_MIN_ITEMS`] items and [`RATE_MIN_SECONDS`] seconds).
    pub items_per_hour: Option<f64>,
    /// Estimated seconds to finish at that rate.
    pub eta_seconds: Option<f64>,
    /// Sum of finished items' seconds.
    pub item_seconds: f64,
}

/// Items that must have finished before a rate is estimated: fewer give rates that mean
/// nothing (one fast item in 10 ms reads as 360,000 an hour).
pub const RATE_MIN_ITEMS: u64 = 5;
/// Seconds that must have passed before a rate is estimated, for the same reason.
pub const RATE_MIN_SECONDS: f64 = 10.0;

/// `items` finished in `seconds` as items per hour, or `None` while fewer than
/// [`RATE_MIN_ITEMS`] items or [`RATE_MIN_SECONDS`] seconds make the estimate meaningless.
pub fn rate_per_hour(items: u64, seconds: f64) -> Option<f64> {
    (items >= RATE_MIN_ITEMS && seconds >= RATE_MIN_SECONDS)
        .then(|| items as f64 / seconds * 3600.0)
}

/// Every shard's state, its record checked with `check` (in parallel: a check may hash the
/// shard file).
pub fn shard_states(job: &Job, check: Check) -> Result<Vec<ShardState>> {
    (0..job.file.shards)
        .into_par_iter()
        .map(|shard| Ok(shard_state(&job.layout, shard, job.fingerprint(), check)?))
        .collect()
}

/// Reads the progress of a job, finished shards checked quickly ([`Check::Quick`]).
pub fn summarize(job: &Job) -> Result<JobSummary> {
    Ok(summarize_states(job, &shard_states(job, Check::Quick)?))
}

/// The progress of a job whose shard states are known.
pub fn summarize_states(job: &Job, states: &[ShardState]) -> JobSummary {
    let mut s = JobSummary {
        shards: job.file.shards,
        items: job.file.items,
        ..Default::default()
    };
    let now = sparc3d_workers::clock::now();
    let (mut first, mut last) = (f64::INFINITY, 0.0f64);
    for (shard, state) in (0..job.file.shards).zip(states) {
        match state {
            ShardState::Done(r) => {
                s.shards_done += 1;
                s.ok += r.ok;
                s.failed += r.failed;
                s.item_seconds += r.item_seconds;
                for (k, v) in &r.error_classes {
                    *s.error_classes.entry(k.clone()).or_default() += v;
                }
                first = first.min(r.started_at);
                last = last.max(r.finished_at);
                continue;
            }
            ShardState::Running(_) => s.shards_running += 1,
            ShardState::Pending => s.shards_pending += 1,
            ShardState::Damaged(reason) => {
                s.shards_damaged += 1;
                s.damaged.push(DamagedShard {
                    shard,
                    reason: reason.clone(),
                });
            }
        }
        let Ok(js) = sparc3d_workers::journal::set::read(&job.layout, shard, None) else {
            continue;
        };
        if let Some(c) = js.created_at {
            first = first.min(c);
        }
        for d in js.done.values() {
            match d.status {
                ItemStatus::Ok => s.ok += 1,
                _ => s.failed += 1,
            }
            if let Some(c) = d.class {
                *s.error_classes.entry(c.as_str().to_string()).or_default() += 1;
            }
            s.item_seconds += d.total_s;
            last = last.max(d.at);
        }
        if matches!(state, ShardState::Running(_)) {
            for (&index, &at) in &js.in_flight {
                if let Ok(Some(item)) = job.item(index) {
                    s.in_flight.push(InFlight {
                        shard,
                        id: item.record.id.clone(),
                        uri: item.record.uri.clone(),
                        seconds: (now - at).max(0.0),
                    });
                }
            }
        }
    }
    s.pending = s.items.saturating_sub(s.ok + s.failed);
    s.in_flight.sort_by(|a, b| b.seconds.total_cmp(&a.seconds));
    if first.is_finite() {
        let end = if s.shards_running > 0 { now } else { last };
        if let Some(rate) = rate_per_hour(s.ok + s.failed, end - first) {
            s.items_per_hour = Some(rate);
            s.eta_seconds = Some(s.pending as f64 / rate * 3600.0);
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_rate_from_too_few_items_or_too_short_a_time() {
        assert_eq!(rate_per_hour(1, 0.011), None, "one item in 11 ms");
        assert_eq!(rate_per_hour(87, 1.0), None, "a second is too short");
        assert_eq!(rate_per_hour(4, 3600.0), None, "four items are too few");
        assert_eq!(rate_per_hour(100, 60.0), Some(6000.0));
        assert_eq!(
            rate_per_hour(RATE_MIN_ITEMS, RATE_MIN_SECONDS),
            Some(1800.0)
        );
    }
}
