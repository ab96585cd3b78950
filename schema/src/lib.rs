//! Contracts shared by every part of sparc3d: the manifest record and the frozen item, the job
//! config and its fingerprint, the layout of a job folder, the Arrow schema of a shard row and
//! the tensor encodings (dtype, byte order, zstd), the completion record that marks a shard
//! done, and how a digest is written (hex, sha256).
//!
//! This crate does no I/O beyond encoding and decoding its own types.
#![deny(missing_docs)]

pub mod columns;
pub mod error;
pub mod hex;
pub mod job;
pub mod row;

pub use error::{Result, SchemaError};
pub use job::completion::{CompletionRecord, FileStamp};
pub use job::config::{AttributeConfig, JobConfig, JobFile, Limits, RenderConfig, SampleConfig};
pub use job::layout::JobLayout;
pub use job::manifest::{FrozenItem, ManifestPage, ManifestRecord, SliceEntry};
pub use row::class::{ErrorClass, ItemStatus};
pub use row::quality::QualityFacts;
pub use row::tensor::{DType, EncodedTensor};
pub use row::{
    AppearanceFacts, AttributeTensors, RenderedView, RowCounts, RowRenders, RowTensors, RowTimings,
    SampleTensors, ShardRow,
};

/// Version of the shard format; bumped when a stored column changes its type, encoding or
/// meaning, so that a job is never a mix of versions. Version 2 stores tensor bytes in byte
/// planes (version 1: row-major); version 3 puts zstd's content checksum in every tensor blob,
/// so any zstd decoder fails loudly on a damaged blob, and adds the optional vector-set sample
/// columns with the `<f2` and `<u1` dtypes. Adding columns does not bump it: a new group of
/// columns comes behind a config key whose absence reads as off, and a new column in a group
/// is optional on read, so a shard written before either reads as it always did and recomputes
/// the content digest it was written with (the rule: [`columns::table`], "How the schema
/// evolves").
pub const SCHEMA_VERSION: u32 = 3;

/// Version of the tool that wrote a file (the workspace version).
pub const TOOL_VERSION: &str = env!("CARGO_PKG_VERSION");

/// Parquet key-value metadata keys written into every shard.
pub mod meta_keys {
    /// The shard format's schema version ([`crate::SCHEMA_VERSION`]).
    pub const SCHEMA_VERSION: &str = "sparc3d.schema_version";
    /// The job config as JSON.
    pub const CONFIG: &str = "sparc3d.config";
    /// The config fingerprint.
    pub const FINGERPRINT: &str = "sparc3d.fingerprint";
    /// The version of the tool that wrote the shard.
    pub const TOOL_VERSION: &str = "sparc3d.tool_version";
    /// The shard's index in its job.
    pub const SHARD_INDEX: &str = "sparc3d.shard_index";
}
