//! The shard store: a job's finished shards on disk and their completion records, in one
//! place. [`write`](mod@write) writes a shard (Parquet under a temporary name → fsync → [`commit`]:
//! linked to the shard's name, never over another writer's, completion record last);
//! [`state`] checks a shard against its record (done, damaged, running, pending), moves a
//! damaged one aside and verifies; [`read`] reads rows back, also the rows of a shard still
//! in its journals; [`footer`] reads a shard file's footer.
//!
//! It lives in `sparc3d-workers`, next to the journal it reads unfinished rows from and the
//! shard loop that writes, rather than in a crate of its own: every reader (the CLI, the
//! orchestrator) already links this crate, and writing needs the journal.

pub mod commit;
pub mod footer;
pub mod read;
pub mod state;
pub mod write;
