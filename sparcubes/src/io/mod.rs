//! Loading and saving meshes: OBJ, PLY, STL, OFF, glTF/GLB in; PLY, OBJ, STL, GLB out.

use crate::error::Result;
use crate::mesh::TriMesh;
use std::path::Path;

/// What loading skipped or repaired, for the conversion summary and shard rows.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LoadStats {
    /// Polygons with more than three corners that were triangulated.
    pub polygons_triangulated: u64,
    /// Point primitives skipped.
    pub points_skipped: u64,
    /// Line primitives skipped.
    pub lines_skipped: u64,
    /// Faces dropped because an index was out of range.
    pub faces_bad_index: u64,
    /// Faces dropped because a corner had a non-finite coordinate.
    pub faces_non_finite: u64,
}

/// A loaded, sanitised mesh and what loading did to it.
#[derive(Debug, Clone, Default)]
pub struct LoadedMesh {
    /// The mesh (indices valid, coordinates finite, at least one triangle).
    pub mesh: TriMesh,
    /// What was skipped or repaired.
    pub stats: LoadStats,
}

/// Loads a mesh file, choosing the format by extension (then by content), and sanitises it.
pub fn load(path: &Path) -> Result<LoadedMesh> {
    let _ = path;
    unimplemented!("io::load is being written")
}

/// Saves a mesh; the format follows the extension (`.ply`, `.obj`, `.stl`, `.glb`).
pub fn save(mesh: &TriMesh, path: &Path) -> Result<()> {
    let _ = (mesh, path);
    unimplemented!("io::save is being written")
}
