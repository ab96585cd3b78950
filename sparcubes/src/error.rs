//! Typed errors of the geometry crate. Every error names what failed and why; the pipeline
//! maps them to stable error classes with [`Error::class`].

use std::path::PathBuf;

/// Stable, machine-readable class of an [`Error`], stored in shard rows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ErrorClass {
    /// The file could not be parsed (malformed, truncated, garbage).
    ParseError,
    /// The file's format is not supported.
    UnsupportedFormat,
    /// Nothing usable was left after sanitising (no finite, valid triangle).
    EmptyMesh,
    /// Reading or writing a file failed.
    IoError,
    /// The parameters are out of range.
    InvalidParams,
    /// The input exceeds a configured size limit.
    TooLarge,
}

impl ErrorClass {
    /// The snake_case name stored in shard rows and shown to users.
    pub const fn as_str(self) -> &'static str {
        match self {
            ErrorClass::ParseError => "parse_error",
            ErrorClass::UnsupportedFormat => "unsupported_format",
            ErrorClass::EmptyMesh => "empty_mesh",
            ErrorClass::IoError => "io_error",
            ErrorClass::InvalidParams => "invalid_params",
            ErrorClass::TooLarge => "too_large",
        }
    }
}

/// Everything that can go wrong in loading, converting or saving a mesh.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be parsed.
    #[error("{path}: cannot parse: {reason}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// What was wrong.
        reason: String,
    },
    /// A file's format is not supported (by extension or content).
    #[error("{path}: unsupported format: {reason}")]
    UnsupportedFormat {
        /// The file.
        path: PathBuf,
        /// Which format, and what is supported.
        reason: String,
    },
    /// No surface is left after dropping invalid faces.
    #[error("{context}: empty mesh: {reason}")]
    EmptyMesh {
        /// The file, or a description of the in-memory mesh.
        context: String,
        /// Why nothing is left (e.g. counts of what was dropped).
        reason: String,
    },
    /// An I/O error on a file.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A parameter is out of range.
    #[error("invalid parameter: {0}")]
    InvalidParams(String),
    /// The input is larger than a configured limit.
    #[error("{context}: too large: {reason}")]
    TooLarge {
        /// The file or mesh.
        context: String,
        /// Which limit was exceeded.
        reason: String,
    },
}

impl Error {
    /// The stable class of this error.
    pub fn class(&self) -> ErrorClass {
        match self {
            Error::Parse { .. } => ErrorClass::ParseError,
            Error::UnsupportedFormat { .. } => ErrorClass::UnsupportedFormat,
            Error::EmptyMesh { .. } => ErrorClass::EmptyMesh,
            Error::Io { .. } => ErrorClass::IoError,
            Error::InvalidParams(_) => ErrorClass::InvalidParams,
            Error::TooLarge { .. } => ErrorClass::TooLarge,
        }
    }
}

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
