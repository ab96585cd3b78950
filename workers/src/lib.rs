//! Processing of one shard of a sparc3d job: claim it, convert each item in isolation,
//! checkpoint finished items, and write the Parquet shard atomically.
//!
//! Rooms, one role each: [`job`] (read a job folder; are its files as `init` wrote them,
//! [`job::files`]; no frozen manifest changes under a run, [`job::lock`]), [`frozen`] (its frozen
//! manifest, in slices a shard's task reads alone), [`lease`] (who works on a shard),
//! [`journal`] (finished items, appended and fsynced, as [`journal::record`]s), [`item`] (an
//! item's bytes, from disk or fetched from a URL, and the one function that touches geometry),
//! [`isolate`] (the isolated process that runs it, its supervisor and the child-process
//! plumbing), [`shard`] (a shard: lease, resume, write; its items converted a few at once, as
//! many as [`shard::lanes`] says, reported as [`shard::events`]; how, [`work_options`] holds),
//! [`store`] (shards on disk: write, check against their completion records, read back) and
//! [`clock`] (the wall clock).
#![deny(missing_docs)]

pub mod clock;
pub mod error;
pub mod frozen;
pub mod fsutil;
pub mod isolate;
pub mod item;
pub mod job;
pub mod journal;
pub mod lease;
pub mod shard;
pub mod store;
pub mod work_options;

pub use error::{Result, WorkerError};
pub use job::Job;
pub use shard::{process_shard, ShardOutcome};
pub use work_options::WorkOptions;
