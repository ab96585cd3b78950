//! Stage 7: sparse marching cubes over the active cells with the deformed vertex positions.

use crate::cubes::SparseCubes;
use crate::mesh::TriMesh;

/// Extracts the closed, 2-manifold, outward-oriented mesh of `cubes`, in grid coordinates
/// (voxels). Use [`crate::Normalization::grid_to_source`] to map it back.
pub fn extract(cubes: &SparseCubes) -> TriMesh {
    let _ = cubes;
    unimplemented!("extract is being written")
}
