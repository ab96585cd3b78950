//! How shards are processed ([`WorkOptions`]): the item worker to start, the per-item limits,
//! the lease lifetime, the stop flag, where progress events go, what runs after each item and
//! how many items convert at once. Set by whoever processes shards (`work`, a bucket job's
//! worker), read by the shard loop and the loop over its items.

use crate::error::Result;
use crate::isolate::supervisor::ChildCommand;
use crate::journal::Journal;
use crate::shard::events::Event;
use crate::shard::lanes::LaneBudget;
use sparc3d_schema::Limits;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// What [`WorkOptions::after_item`] calls after each item.
pub type AfterItem = Box<dyn FnMut(&Journal) -> Result<()> + Send>;

/// How to process shards.
pub struct WorkOptions {
    /// How to start the item worker process.
    pub child: ChildCommand,
    /// Per-item limits for this run.
    pub limits: Limits,
    /// Seconds a lease stays valid without a heartbeat.
    pub lease_ttl_s: f64,
    /// Set to stop cleanly (Ctrl-C): the item in flight is abandoned, not counted.
    pub stop: Arc<AtomicBool>,
    /// Receives progress events.
    pub events: Box<dyn FnMut(Event) + Send>,
    /// Called after each item's final result is journalled (an item boundary: its journal
    /// holds whole item histories), with this holder's journal; an error stops the shard.
    /// A job whose home is a bucket uploads checkpoints here.
    pub after_item: Option<AfterItem>,
    /// Items converted at once and threads each ([`LaneBudget::single`]: one at a time).
    pub budget: Arc<LaneBudget>,
}
