//! Progress events of a worker, printed one JSON object per line by `sparc3d work --events`
//! and read by the local orchestrator.

use serde::{Deserialize, Serialize};

/// Something that happened while processing shards.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum Event {
    /// A shard was claimed; `done` of its `items` were already finished.
    ShardStarted {
        /// Shard index.
        shard: u64,
        /// Items in the shard.
        items: u64,
        /// Items already finished (resumed from the journal).
        done: u64,
    },
    /// An item started.
    ItemStarted {
        /// Shard index.
        shard: u64,
        /// Item index.
        index: u64,
        /// Item id.
        id: String,
        /// Source path.
        uri: String,
    },
    /// An item finished (final outcome, or a crash that will be retried).
    ItemFinished {
        /// Shard index.
        shard: u64,
        /// Item index.
        index: u64,
        /// `ok`, `failed`, or `retry` for a crash that will be retried.
        status: String,
        /// Error class when failed.
        class: Option<String>,
        /// Seconds the item took.
        seconds: f64,
    },
    /// Every item of a shard is finished; the worker now writes the shard file (and starts
    /// no other item), so an orchestrator may start the next shard beside it.
    ShardWriting {
        /// Shard index.
        shard: u64,
    },
    /// A shard was written and its completion record made.
    ShardFinished {
        /// Shard index.
        shard: u64,
        /// Rows.
        rows: u64,
        /// Ok rows.
        ok: u64,
        /// Failed rows.
        failed: u64,
    },
    /// A finished shard did not match its completion record (or the record was torn): both
    /// were moved aside and the shard is converted again.
    ShardDamaged {
        /// Shard index.
        shard: u64,
        /// What was wrong.
        reason: String,
        /// The folder the damaged files were moved to.
        moved_to: String,
    },
    /// The worker lost the shard's lease (stopped past it, or taken over) and left the shard.
    LeaseLost {
        /// Shard index.
        shard: u64,
        /// What happened, naming the lease file.
        message: String,
    },
    /// A shard was not processed (already done, or leased by another worker).
    ShardSkipped {
        /// Shard index.
        shard: u64,
        /// Why.
        reason: String,
    },
}
