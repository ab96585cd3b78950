//! What a fetch gives, whichever way the object came (`object_store` for buckets, `http` for
//! `http(s)://`): its bytes and their sha256 ([`Fetched`]), and the two rules both ways keep:
//! the most bytes reserved before any arrived, and the error for an object over the byte cap.

use crate::error::{FetchError, FetchErrorKind};
use crate::location::RemoteUrl;

/// The bytes of a fetched object and their sha256 (lower-case hex).
#[derive(Debug, Clone)]
pub struct Fetched {
    /// The object's bytes.
    pub bytes: Vec<u8>,
    /// Their sha256.
    pub sha256: String,
}

/// The most bytes reserved from an announced size before any arrived.
pub(crate) const PREALLOCATE_AT_MOST: u64 = 256 << 20;

/// The error for the object at `url` over the byte cap `cap`: it is `size` bytes (a number,
/// or "more than N" when the body outgrew the cap as it streamed).
pub(crate) fn too_large(url: &RemoteUrl, size: String, cap: u64) -> FetchError {
    FetchError::new(
        url.to_string(),
        FetchErrorKind::TooLarge,
        format!("the object is {size} bytes, over the cap of {cap} (SPARC3D_FETCH_MAX_BYTES)"),
    )
}
