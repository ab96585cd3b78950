//! Processing of one shard of a sparc3d job: claim it, convert each item in isolation,
//! checkpoint finished items, and write the Parquet shard atomically.
//!
//! Roles, one module each: [`job`] (read a job folder), [`frozen`] (its frozen manifest, in
//! slices a shard's task reads alone), [`job_files`] (are its files as `init`
//! wrote them), [`job_lock`] (no frozen manifest changes under a run), [`lease`] (who works on
//! a shard), [`journal`] (finished items, appended and fsynced), [`source`] (an item's bytes,
//! from disk or fetched from a URL), [`convert`] (the one function that touches geometry), [`child`] (the isolated
//! process that runs it), [`process`] (the one child-process supervisor: stderr tail,
//! parent-death signal, time limit, resource use), [`supervisor`] (runs items in a child, with
//! a watchdog, and classifies its deaths), [`shard`] (a shard: lease, resume, write; its items converted a few at once by
//! `item_loop`, as many as [`lanes`] says; how, [`work_options`] holds), [`store`]
//! (shards on disk: write, check against their completion records, read back), [`events`]
//! (progress reports).
#![deny(missing_docs)]

pub mod child;
pub mod convert;
pub mod error;
pub mod events;
pub mod frame;
pub mod frozen;
pub mod fsutil;
mod item_loop;
pub mod job;
pub mod job_files;
pub mod job_lock;
pub mod journal;
pub mod lanes;
pub mod lease;
pub mod parent;
pub mod process;
pub mod quality;
pub mod shard;
pub mod source;
pub mod store;
pub mod supervisor;
pub mod work_options;

pub use error::{Result, WorkerError};
pub use job::Job;
pub use shard::{process_shard, ShardOutcome};
pub use work_options::WorkOptions;

/// Seconds since the Unix epoch.
pub fn now() -> f64 {
    since_epoch().as_secs_f64()
}

/// Time since the Unix epoch (zero on a clock set before it), for times and unique names.
pub fn since_epoch() -> std::time::Duration {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default()
}
