//! Sparcubes: sparse deformable marching cubes (after "Sparc3D: Sparse Representation and
//! Construction for High-Resolution 3D Shapes Modeling").
//!
//! Any triangle mesh becomes a sparse cube grid with a signed distance and a deformation on
//! every active vertex ([`SparseCubes`]), from which a watertight, 2-manifold mesh is
//! extracted. Closed parts keep their true surface, open parts become thin closed shells, and
//! no component is dropped. The stages of [`convert`] are free functions over plain data, one
//! module each:
//!
//! 1. [`normalize`] — fit the mesh into the grid with a margin,
//! 2. [`voxelize`] — wall cells (cells a triangle touches) and grid edges a triangle crosses,
//! 3. [`flood`] — outside cells by a hierarchical flood fill (bricks, then cells); [`seal`] —
//!    openings small for their part sealed, so nearly closed solids stay solid,
//! 4. [`band`] — exact unsigned distance and closest point on the vertices near the surface,
//! 5. [`sign`] — inside/outside per vertex, thin-shell treatment of open parts,
//! 6. [`deform`] — φ and the bounded displacement of each vertex towards the surface; [`ring`]
//!    — the surface-free cells next to the walls a thin shell reaches, with their own band,
//! 7. [`extract`] — marching cubes over the active cells → closed manifold mesh; [`refine`]
//!    (optional, paper step 4) — the displacements refined against renderings of the source.
//!
//! The crate knows nothing of jobs or file formats beyond loading and saving meshes ([`io`]).
//! Quality metrics and preview pictures are crates of their own (`sparc3d-metrics`,
//! `sparc3d-render`, ARCHITECTURE.md says why); the generated test meshes of `shapes` are built
//! only with the `test-shapes` feature, which tests turn on through `[dev-dependencies]`.
#![deny(missing_docs)]
// Geometry code indexes several arrays by the same axis or word number; iterator chains would
// hide that parallel structure.
#![allow(clippy::needless_range_loop)]

pub mod attributes;
pub mod band;
pub mod close_grid;
pub mod closest;
pub mod convert;
pub mod cubes;
pub mod deform;
pub mod duplicate_faces;
pub mod error;
pub mod extract;
pub mod flood;
pub mod grid;
pub mod holes;
pub mod io;
pub mod layouts;
pub mod materials;
pub mod mc_table;
pub mod mesh;
pub mod morton;
pub mod normalize;
pub mod params;
pub mod refine;
pub mod regions;
pub mod ring;
pub mod samples;
pub mod sanitize;
pub mod seal;
#[cfg(feature = "test-shapes")]
pub mod shapes;
pub mod sides;
pub mod sign;
pub mod topology;
pub mod vec3;
pub mod voxelize;
pub mod winding;

pub use convert::{convert, Conversion, ConvertStats};
pub use cubes::SparseCubes;
pub use error::{Error, ErrorClass};
pub use extract::extract;
pub use mesh::TriMesh;
pub use normalize::Normalization;
pub use params::Params;
