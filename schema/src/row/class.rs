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

/// Stable class of a failed item: the class the geometry crate gave the error
/// (`sparcubes::ErrorClass`), or one that describes how the isolated worker died or what
/// failed around the conversion. Stored by its name ([`ErrorClass::as_str`]), in serde too
/// (`"parse_error"` in JSON, as a derived unit-only enum writes it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(into = "&'static str", try_from = "String")]
pub enum ErrorClass {
    /// Loading or converting the mesh failed: parse error, unsupported format, empty mesh,
    /// I/O error, invalid parameters, input too large.
    Geometry(sparcubes::ErrorClass),
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
    /// Every class, in a stable order (the order they sort in).
    pub const ALL: [ErrorClass; 14] = {
        use sparcubes::ErrorClass as G;
        [
            ErrorClass::Geometry(G::ParseError),
            ErrorClass::Geometry(G::UnsupportedFormat),
            ErrorClass::Geometry(G::EmptyMesh),
            ErrorClass::Geometry(G::IoError),
            ErrorClass::Geometry(G::InvalidParams),
            ErrorClass::Geometry(G::TooLarge),
            ErrorClass::Panic,
            ErrorClass::StackOverflow,
            ErrorClass::Timeout,
            ErrorClass::OutOfMemory,
            ErrorClass::Crashed,
            ErrorClass::EncodeError,
            ErrorClass::SourceChanged,
            ErrorClass::Fetch,
        ]
    };

    /// The snake_case name stored in the `error_class` column.
    pub const fn as_str(self) -> &'static str {
        match self {
            ErrorClass::Geometry(g) => g.as_str(),
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

/// Serde writes a class as its name.
impl From<ErrorClass> for &'static str {
    fn from(c: ErrorClass) -> Self {
        c.as_str()
    }
}

/// Serde reads a class from its name.
impl TryFrom<String> for ErrorClass {
    type Error = SchemaError;

    fn try_from(name: String) -> Result<Self> {
        Self::parse(&name)
    }
}

impl From<sparcubes::ErrorClass> for ErrorClass {
    fn from(c: sparcubes::ErrorClass) -> Self {
        ErrorClass::Geometry(c)
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
        let unknown = serde_json::from_str::<ErrorClass>("\"nope\"").err();
        assert_eq!(
            unknown.map(|e| e.to_string()),
            Some("invalid error class: nope".to_string())
        );
        let counts = std::collections::BTreeMap::from([(ErrorClass::Timeout, 2u64)]);
        let json = serde_json::to_string(&counts).unwrap_or_default();
        assert_eq!(json, r#"{"timeout":2}"#, "a class is a map key by its name");
        let back: std::collections::BTreeMap<ErrorClass, u64> =
            serde_json::from_str(&json).unwrap_or_default();
        assert_eq!(back, counts);
        let ordered = ErrorClass::ALL.windows(2).all(|w| w[0] < w[1]);
        assert!(ordered, "ALL is in the order classes sort in");
        assert_eq!(ItemStatus::parse("failed").ok(), Some(ItemStatus::Failed));
    }
}
