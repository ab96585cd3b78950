//! Meshes and the tools that work on a whole mesh, apart from the conversion's stages.
//!
//! - [`tri_mesh`] — [`TriMesh`], the indexed triangle mesh that is read, converted and written.
//! - [`grid_mesh`] — [`GridMesh`], a mesh in grid coordinates, as the stages see it.
//! - [`triangle`] — the closest point on one triangle.
//! - [`sanitize`] — faces with out-of-range indices or non-finite corners dropped, and
//!   unused vertices; [`duplicate_faces`] — triangles that repeat an earlier one's three
//!   vertices dropped (both at load).
//! - [`topology`] — welding, closedness, 2-manifoldness, components.
//! - [`holes`] — hole filling by smallest-angle ears.

pub mod duplicate_faces;
pub mod grid_mesh;
pub mod holes;
pub mod sanitize;
pub mod topology;
pub mod tri_mesh;
pub mod triangle;

pub use grid_mesh::GridMesh;
pub use tri_mesh::TriMesh;
