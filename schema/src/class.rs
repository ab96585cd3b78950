//! Item statuses and error classes, as stored in the `status` and `error_class` columns.

use crate::error::{Result, SchemaError};
use serde::{Deserialize, Serialize};

/// Outcome of one item.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ItemStatus {
    /// Converted; the tensors are present.
    Ok,
    /// Not converted; `error_class` and `error_message` say why.
    Failed,
    /// Deliberately not converted (reserved for filters; never written today).
    Skipped,
}

impl ItemStatus {
    /// The name stored in the `status` column.
    pub fn as_str(self) -> &'static str {
        match self {
            ItemStatus::Ok => "ok",
            ItemStatus::Failed => "failed",
            ItemStatus::Skipped => "skipped",
        }
    }

    /// Parses a stored status.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "ok" => Ok(ItemStatus::Ok),
            "failed" => Ok(ItemStatus::Failed),
            "skipped" => Ok(ItemStatus::Skipped),
            other => Err(SchemaError::Invalid {
                what: "status",
                value: other.to_string(),
            }),
        }
    }
}

/// Stable class of a failed item. Geometry classes come from `sparcubes::ErrorClass`; the
/// others describe how the isolated worker died.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ErrorClass {
    /// The file could not be parsed.
    ParseError,
    /// The file's format is not supported.
    UnsupportedFormat,
    /// Nothing usable was left after sanitising.
    EmptyMesh,
    /// Reading the input failed (missing file, permissions).
    IoError,
    /// The conversion parameters are out of range.
    InvalidParams,
    /// The input exceeds a configured size limit.
    TooLarge,
    /// The conversion panicked (a bug; the message says where).
    Panic,
    /// The conversion overflowed its stack.
    StackOverflow,
    /// The item ran past the per-item time limit.
    Timeout,
    /// The item ran past the per-item memory limit.
    OutOfMemory,
    /// The item's process died otherwise (killed by a signal, aborted).
    Crashed,
    /// Encoding the result into tensors failed.
    EncodeError,
    /// The file's bytes are not the ones the manifest froze (their sha256 differs): it
    /// changed after `init`, so it was not converted under the item's id.
    SourceChanged,
    /// A remote source could not be fetched: gone (404), timed out, truncated, failing its
    /// sha256, refused for its credentials, or its uri names no readable scheme. Retried by
    /// `sparc3d retry JOB --class fetch` once the cause is cleared.
    Fetch,
}

impl ErrorClass {
    /// Every class, in a stable order.
    pub const ALL: [ErrorClass; 14] = [
        ErrorClass::ParseError,
        ErrorClass::UnsupportedFormat,
        ErrorClass::EmptyMesh,
        ErrorClass::IoError,
        ErrorClass::InvalidParams,
        ErrorClass::TooLarge,
        ErrorClass::Panic,
        ErrorClass::StackOverflow,
        ErrorClass::Timeout,
        ErrorClass::OutOfMemory,
        ErrorClass::Crashed,
        ErrorClass::EncodeError,
        ErrorClass::SourceChanged,
        ErrorClass::Fetch,
    ];

    /// The snake_case name stored in the `error_class` column.
    pub fn as_str(self) -> &'static str {
        match self {
            ErrorClass::ParseError => "parse_error",
            ErrorClass::UnsupportedFormat => "unsupported_format",
            ErrorClass::EmptyMesh => "empty_mesh",
            ErrorClass::IoError => "io_error",
            ErrorClass::InvalidParams => "invalid_params",
            ErrorClass::TooLarge => "too_large",
            ErrorClass::Panic => "panic",
            ErrorClass::StackOverflow => "stack_overflow",
            ErrorClass::Timeout => "timeout",
            ErrorClass::OutOfMemory => "out_of_memory",
            ErrorClass::Crashed => "crashed",
            ErrorClass::EncodeError => "encode_error",
            ErrorClass::SourceChanged => "source_changed",
            ErrorClass::Fetch => "fetch",
        }
    }

    /// Parses a stored class name.
    pub fn parse(s: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|c| c.as_str() == s)
            .ok_or_else(|| SchemaError::Invalid {
                what: "error class",
                value: s.to_string(),
            })
    }

    /// Whether a failure of this class is retried automatically: only a process death with
    /// no deterministic cause (`crashed`), which may come from outside (a kill, the OOM killer).
    pub fn is_crash(self) -> bool {
        matches!(self, ErrorClass::Crashed)
    }
}

impl From<sparcubes::ErrorClass> for ErrorClass {
    fn from(c: sparcubes::ErrorClass) -> Self {
        match c {
            sparcubes::ErrorClass::ParseError => ErrorClass::ParseError,
            sparcubes::ErrorClass::UnsupportedFormat => ErrorClass::UnsupportedFormat,
            sparcubes::ErrorClass::EmptyMesh => ErrorClass::EmptyMesh,
            sparcubes::ErrorClass::IoError => ErrorClass::IoError,
            sparcubes::ErrorClass::InvalidParams => ErrorClass::InvalidParams,
            sparcubes::ErrorClass::TooLarge => ErrorClass::TooLarge,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn class_names_round_trip() {
        for c in ErrorClass::ALL {
            assert_eq!(ErrorClass::parse(c.as_str()).ok(), Some(c));
            let json = serde_json::to_string(&c).unwrap_or_default();
            assert_eq!(json, format!("\"{}\"", c.as_str()));
        }
        assert!(ErrorClass::parse("nope").is_err());
        assert_eq!(ItemStatus::parse("failed").ok(), Some(ItemStatus::Failed));
    }
}
