//! Errors of encoding and decoding the contracts.

/// What went wrong while encoding or decoding a contract type.
#[derive(Debug, thiserror::Error)]
pub enum SchemaError {
    /// A tensor blob did not decode (bad zstd stream, wrong length, wrong dtype).
    #[error("tensor {name}: {reason}")]
    Tensor {
        /// Which tensor.
        name: String,
        /// What was wrong.
        reason: String,
    },
    /// A column is missing or has an unexpected type.
    #[error("column {name}: {reason}")]
    Column {
        /// Which column.
        name: String,
        /// What was wrong.
        reason: String,
    },
    /// A value is not one of those allowed (status, error class, config key).
    #[error("invalid {what}: {value}")]
    Invalid {
        /// What kind of value.
        what: &'static str,
        /// The offending value, with context.
        value: String,
    },
    /// JSON (config, manifest line, record) did not parse or serialize.
    #[error("{context}: {source}")]
    Json {
        /// What was being read or written.
        context: String,
        /// The underlying error.
        #[source]
        source: serde_json::Error,
    },
    /// Building an Arrow record batch failed.
    #[error("arrow: {0}")]
    Arrow(#[from] arrow_schema::ArrowError),
    /// zstd compression failed.
    #[error("zstd: {0}")]
    Zstd(#[source] std::io::Error),
}

/// Result with [`SchemaError`].
pub type Result<T, E = SchemaError> = std::result::Result<T, E>;
