//! The conversion driver: the stages of DESIGN.md §3, top to bottom.

use crate::cubes::SparseCubes;
use crate::error::Result;
use crate::mesh::TriMesh;
use crate::params::Params;

/// Wall-clock seconds and counts of one conversion.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ConvertStats {
    /// Seconds per stage, in order: (stage name, seconds).
    pub stage_seconds: Vec<(&'static str, f64)>,
    /// Input triangles.
    pub input_faces: u64,
    /// Input vertices.
    pub input_vertices: u64,
    /// Cells touched by the surface.
    pub wall_cells: u64,
    /// Active vertices stored.
    pub active_vertices: u64,
    /// Active cells stored.
    pub active_cells: u64,
    /// Vertices treated as part of a thin shell (open surfaces).
    pub shell_vertices: u64,
}

/// A conversion's result.
#[derive(Debug, Clone)]
pub struct Conversion {
    /// The sparse cubes.
    pub cubes: SparseCubes,
    /// Timings and counts.
    pub stats: ConvertStats,
}

/// Converts a sanitised mesh into sparse cubes.
pub fn convert(mesh: &TriMesh, params: &Params) -> Result<Conversion> {
    let _ = (mesh, params);
    unimplemented!("convert is being written")
}
