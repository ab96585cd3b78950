//! What a manifest is: the table of meshes a job converts, read from CSV, JSONL or Parquet
//! ([`table`]) and written by `manifest build` ([`write`]) with its path column chosen by one rule ([`path_column`]) or made by scanning a
//! folder ([`folder_scan`]); files identified by their sha256 ([`hash`]); and the rows frozen
//! into a job's items, each with its index and shard ([`freeze`], [`record`]).
//!
//! It knows nothing of shards' contents, workers or the command line: `sparc3d-schema` builds
//! shard rows from the frozen items, and the `sparc3d` binary's commands (`manifest build`,
//! `init`, `run --job`) call this crate.
#![deny(missing_docs)]

pub mod filter;
pub mod folder_scan;
pub mod freeze;
pub mod hash;
pub mod path_column;
pub mod record;
pub mod table;
pub mod tsv;
pub mod write;

pub use record::{FrozenItem, ManifestRecord};
pub use table::{Manifest, RawRecord};
