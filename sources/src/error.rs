//! Why a remote object could not be fetched or listed, with the URL it concerns.

use std::fmt;

/// What kind of failure a [`FetchError`] is; the worker's failure class follows from it
/// ([`FetchErrorKind::TooLarge`] is `too_large`, every other kind `fetch`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FetchErrorKind {
    /// The uri names nothing sparc3d can read (unknown scheme, no bucket, credentials in it).
    Location,
    /// The object does not exist (404, no such key).
    NotFound,
    /// No connection or no bytes within the time-outs, after every retry.
    Timeout,
    /// No usable credentials, or the store refused them (401/403).
    Credentials,
    /// The object is larger than the byte cap.
    TooLarge,
    /// The body ended before the size the server announced.
    Truncated,
    /// The bytes' sha256 is not the one the manifest gives.
    Checksum,
    /// Anything else (server errors after every retry, a listing that failed, ...).
    Other,
}

impl FetchErrorKind {
    /// A short name for messages and tests.
    pub fn as_str(self) -> &'static str {
        match self {
            FetchErrorKind::Location => "bad location",
            FetchErrorKind::NotFound => "not found",
            FetchErrorKind::Timeout => "timed out",
            FetchErrorKind::Credentials => "credentials",
            FetchErrorKind::TooLarge => "too large",
            FetchErrorKind::Truncated => "truncated",
            FetchErrorKind::Checksum => "checksum mismatch",
            FetchErrorKind::Other => "failed",
        }
    }
}

/// A failed fetch or listing: the URL, the kind and what happened.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FetchError {
    /// The URL (never with credentials: URLs holding them are refused).
    pub url: String,
    /// The kind of failure.
    pub kind: FetchErrorKind,
    /// What happened, in words (the store's error chain, or our own check).
    pub message: String,
}

impl FetchError {
    /// An error of `kind` on `url`.
    pub fn new(url: impl Into<String>, kind: FetchErrorKind, message: impl Into<String>) -> Self {
        Self {
            url: url.into(),
            kind,
            message: message.into(),
        }
    }

    /// The error `object_store` gave for `url`, classified by what it says.
    pub(crate) fn from_store(url: &str, e: &object_store::Error) -> Self {
        let chain = chain(e);
        let lower = chain.to_ascii_lowercase();
        // Where the clouds' metadata services answer: reached only when nothing else gave
        // credentials (object_store's last resort).
        let metadata = [
            "/latest/api/token",
            "/latest/meta-data",
            "computemetadata",
            "/metadata/identity",
        ]
        .iter()
        .any(|m| lower.contains(m));
        let kind = if matches!(e, object_store::Error::NotFound { .. }) {
            FetchErrorKind::NotFound
        } else if metadata
            || lower.contains("credential")
            || lower.contains("status: 401")
            || lower.contains("status: 403")
            || lower.contains("403 forbidden")
            || lower.contains("401 unauthorized")
        {
            FetchErrorKind::Credentials
        } else if lower.contains("timed out") || lower.contains("timeout") {
            FetchErrorKind::Timeout
        } else {
            FetchErrorKind::Other
        };
        let message = match kind {
            FetchErrorKind::NotFound => format!("not found ({chain})"),
            FetchErrorKind::Credentials if metadata => format!(
                "no credentials: none in the environment or the credential files, and the \
                 cloud's metadata service failed ({chain}); credentials are read from the \
                 environment, the usual credential files and the metadata service: \
                 docs/CLUSTER.md, \"Remote sources\""
            ),
            FetchErrorKind::Credentials => format!(
                "{chain} (credentials are read from the environment, the usual credential \
                 files and the cloud's metadata service: docs/CLUSTER.md, \"Remote sources\")"
            ),
            _ => chain,
        };
        Self::new(url, kind, message)
    }
}

impl fmt::Display for FetchError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.url, self.message)
    }
}

impl std::error::Error for FetchError {}

/// An error and its sources as one line, each step once (object_store's messages often
/// repeat their source's text).
fn chain(e: &dyn std::error::Error) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut next: Option<&dyn std::error::Error> = Some(e);
    while let Some(err) = next {
        let text = err.to_string();
        if !parts.iter().any(|p| p.contains(&text)) {
            parts.push(text);
        }
        next = err.source();
    }
    parts.join(": ")
}
