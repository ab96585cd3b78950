//! The errors of writing an export.

/// Why an item, a listing or the export folder could not be written in a consumer's layout.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The item lacks what the consumer needs (samples, enough points).
    #[error("{0}")]
    Missing(String),
    /// The consumer's own pipeline would leave this item out (Dora's sampler writes nothing
    /// for a mesh without sharp edges): not a failure, counted apart by the export.
    #[error("{0}")]
    LeftOut(String),
    /// A file would exceed what its format can hold.
    #[error("{0}")]
    TooLarge(String),
    /// The item's stored data cannot be turned into the layout.
    #[error("{0}")]
    Invalid(String),
    /// A file or folder of the export could not be written, read or moved.
    #[error("{context}")]
    Io {
        /// What was being done, with the path (`writing out/x.npz`).
        context: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

/// A result with [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
