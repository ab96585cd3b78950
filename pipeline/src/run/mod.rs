//! The local orchestrator: worker processes, their pool and lanes, progress lines, stuck items and signals.

pub mod lane_plan;
pub mod local_workers;
pub mod pool;
pub mod progress;
pub mod signals;
pub mod stuck;
