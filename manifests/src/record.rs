//! Manifest records and frozen items (their types are the contracts of `sparc3d-schema`,
//! [`sparc3d_schema::job::manifest`]), and the columns a manifest's rows are read from.

pub use sparc3d_schema::job::manifest::{FrozenItem, ManifestRecord};

/// Column names accepted for the path of an item, in order of preference.
pub const PATH_COLUMNS: [&str; 5] = ["uri", "path", "local_path", "file", "url"];
/// Column names accepted for the id of an item, in order of preference.
pub const ID_COLUMNS: [&str; 2] = ["id", "sha256"];
/// The columns a manifest row is read into besides its path column; every other column is
/// kept as provenance ([`ManifestRecord::extra`]).
pub const KNOWN_COLUMNS: [&str; 3] = ["id", "sha256", "format"];
