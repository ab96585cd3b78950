//! Contracts shared by every part of sparc3d: the manifest record, the job config and its
//! fingerprint, the Arrow schema of a shard row and the tensor encodings.
#![deny(missing_docs)]

/// Version of the shard format; bumped on any change to columns or encodings.
pub const SCHEMA_VERSION: u32 = 1;
