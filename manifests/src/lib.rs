//! What a manifest is: the table of meshes a job converts, read from CSV, JSONL or Parquet
//! ([`table`] whole, [`stream`] a batch of rows at a time; its path column chosen by one rule:
//! [`path_column`]) and written by `manifest
//! build` ([`mod@write`]), or made by scanning a folder ([`folder_scan`]) or listing a bucket
//! prefix ([`bucket_scan`]); files identified by
//! their sha256 ([`hash`]) and, when they name other files, those too ([`source_id`]); column names read without case, two that fold to one refused
//! ([`columns`]); every other column kept as provenance; rows chosen by `--where`
//! ([`filter`]); and the rows frozen into a job's items, each with its index and shard, or
//! appended to a growing job ([`freeze`], [`record`]).
//!
//! It knows nothing of shards' contents, workers or the command line: `sparc3d-schema` builds
//! shard rows from the frozen items, and the `sparc3d` binary's commands (`manifest build`,
//! `init`, `run --job`, `add`) call this crate.
#![deny(missing_docs)]

pub mod bucket_scan;
pub mod columns;
pub mod filter;
pub mod folder_scan;
pub mod freeze;
pub mod hash;
pub mod path_column;
pub mod problems;
pub mod raw;
pub mod record;
pub mod source_id;
pub mod stream;
pub mod table;
pub mod tsv;
pub mod write;

pub use record::{FrozenItem, ManifestRecord};
pub use table::{Manifest, RawRecord};
