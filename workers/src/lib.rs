//! Processing of one shard of a sparc3d job: claim it, convert each item in isolation,
//! checkpoint finished items, and write the Parquet shard atomically.
#![deny(missing_docs)]
