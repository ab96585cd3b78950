//! A manifest row as its readers make it ([`RawRecord`], before its id is known), and what
//! the whole-file read ([`crate::table`]) and the batch read ([`crate::stream`]) share: a
//! manifest's format from its extension, and a Parquet cell as text.

use crate::record::ManifestRecord;
use arrow_array::{Array, LargeStringArray, StringArray, StringViewArray};
use std::collections::BTreeMap;
use std::path::Path;

/// A manifest row before its id is known: path, optional id / sha256 / format, and the
/// provenance columns.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawRecord {
    /// Optional id.
    pub id: Option<String>,
    /// Absolute path.
    pub uri: String,
    /// Optional sha256.
    pub sha256: Option<String>,
    /// Optional format.
    pub format: Option<String>,
    /// Every other column of the manifest by name, `""` where this row has no value
    /// ([`ManifestRecord::extra`]).
    pub extra: BTreeMap<String, String>,
}

impl RawRecord {
    /// The value of column `name` in this row (a known column or a provenance one); `None`
    /// when the manifest has no such column, `""` when this row has no value in it.
    pub fn column(&self, name: &str) -> Option<&str> {
        match name {
            "id" => Some(self.id.as_deref().unwrap_or("")),
            "uri" | "path" => Some(self.uri.as_str()),
            "sha256" => Some(self.sha256.as_deref().unwrap_or("")),
            "format" => Some(self.format.as_deref().unwrap_or("")),
            other => self.extra.get(other).map(String::as_str),
        }
    }
}

impl From<ManifestRecord> for RawRecord {
    fn from(r: ManifestRecord) -> Self {
        Self {
            id: Some(r.id),
            uri: r.uri,
            sha256: r.sha256,
            format: r.format,
            extra: r.extra,
        }
    }
}

/// The lower-case extension of `path`, which says a manifest's format.
pub(crate) fn ext(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

/// A string cell of a Parquet manifest (any of arrow's three string arrays); `None` for a
/// null or another type.
pub(crate) fn string_at(col: &dyn Array, i: usize) -> Option<String> {
    if col.is_null(i) {
        return None;
    }
    if let Some(a) = col.as_any().downcast_ref::<StringArray>() {
        return Some(a.value(i).to_string());
    }
    if let Some(a) = col.as_any().downcast_ref::<LargeStringArray>() {
        return Some(a.value(i).to_string());
    }
    if let Some(a) = col.as_any().downcast_ref::<StringViewArray>() {
        return Some(a.value(i).to_string());
    }
    None
}

/// A number or boolean cell of a Parquet manifest as text (for provenance columns such as a
/// count or a score; the id, sha256, format and path columns are read as strings only);
/// `None` for other types.
pub(crate) fn number_at(col: &dyn Array, i: usize) -> Option<String> {
    use arrow_array::cast::AsArray;
    use arrow_array::types::{
        Float32Type, Float64Type, Int32Type, Int64Type, UInt32Type, UInt64Type,
    };
    use arrow_schema::DataType as T;
    Some(match col.data_type() {
        T::Boolean => col.as_boolean().value(i).to_string(),
        T::Int32 => col.as_primitive::<Int32Type>().value(i).to_string(),
        T::Int64 => col.as_primitive::<Int64Type>().value(i).to_string(),
        T::UInt32 => col.as_primitive::<UInt32Type>().value(i).to_string(),
        T::UInt64 => col.as_primitive::<UInt64Type>().value(i).to_string(),
        T::Float32 => col.as_primitive::<Float32Type>().value(i).to_string(),
        T::Float64 => col.as_primitive::<Float64Type>().value(i).to_string(),
        _ => return None,
    })
}
