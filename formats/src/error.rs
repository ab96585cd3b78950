//! The errors of writing an export.

/// Why an item (or a listing) could not be written in a consumer's layout.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The item lacks what the consumer needs (samples, sharp edges, enough points).
    #[error("{0}")]
    Missing(String),
    /// A file would exceed what its format can hold.
    #[error("{0}")]
    TooLarge(String),
    /// The item's stored data cannot be turned into the layout.
    #[error("{0}")]
    Invalid(String),
}

/// A result with [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
