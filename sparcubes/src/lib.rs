//! Sparcubes: sparse deformable marching cubes (after "Sparc3D: Sparse Representation and
//! Construction for High-Resolution 3D Shapes Modeling").
//!
//! Any triangle mesh becomes a sparse cube grid with a signed distance and a deformation on
//! every active vertex ([`SparseCubes`]), from which a watertight, 2-manifold mesh is
//! extracted. Closed parts keep their true surface, open parts become thin closed shells, and
//! no component is dropped.
//!
//! The crate is in rooms:
//!
//! - [`grid`] — the grid's data: bricks and their masks, Morton codes, the normalization,
//!   the output [`SparseCubes`];
//! - [`mesh`] — [`TriMesh`], the mesh in grid coordinates, one triangle's closest point, and
//!   the tools on a whole mesh (sanitizing, topology, hole filling);
//! - [`stages`] — the conversion, whose stages [`convert()`] runs in order (numbered as in
//!   docs/ALGORITHM.md): 1 normalize, 2 voxelize (wall cells, crossed grid edges), 3 flood
//!   (outside cells), 4 seal (openings small for their part), 5 band (exact distances near
//!   the surface), 6 the inside test (enclosed regions, sealed vertices, nesting, by the
//!   winding number), 7 sign (sides, thin shells), 8 deform (φ and the displacement), 9 ring
//!   (the cells a thin shell reaches), 10 assemble (the stored cubes); 11 is [`extract()`]
//!   (marching cubes → a closed manifold mesh), and 12, optional, the refinement against
//!   renderings ([`refine`], the paper's step 4);
//! - [`queries`] — closest points, the winding number, the output's inside and outside;
//! - [`products`] — what other crates build on: samples, corner values, dual vertices, the
//!   truncated SDF;
//! - [`io`] — loading and saving meshes;
//! - [`materials`] — a source's appearance as it is read: materials, textures, vertex colours;
//! - [`attributes`] — that appearance sampled at the active cells (PBR on voxels);
//! - [`params`], [`error`] and [`convert`](mod@convert), the driver.
//!
//! The crate knows nothing of jobs, of file formats beyond meshes, or of who reads its
//! products (`sparc3d-formats` does). Quality metrics and preview pictures are crates of their
//! own (`sparc3d-metrics`, `sparc3d-render`, ARCHITECTURE.md says why); the generated test
//! meshes of `shapes` are built only with the `test-shapes` feature, which tests turn on
//! through `[dev-dependencies]`.
#![deny(missing_docs)]
// Geometry code indexes several arrays by the same axis or word number; iterator chains would
// hide that parallel structure.
#![allow(clippy::needless_range_loop)]

pub mod attributes;
pub mod colour;
pub mod convert;
pub mod error;
pub mod grid;
pub mod io;
pub mod materials;
pub mod mesh;
pub mod params;
pub mod products;
pub mod queries;
#[cfg(feature = "test-shapes")]
pub mod shapes;
pub mod stages;
mod union_find;
pub mod vec3;

pub use convert::{convert, Conversion, ConvertStats};
pub use error::{Error, ErrorClass};
pub use grid::cubes::SparseCubes;
pub use grid::normalization::Normalization;
pub use mesh::TriMesh;
pub use params::Params;
pub use stages::extract::extract;

// The paths other crates use, kept from before the rooms.
pub use grid::{cubes, normalization as normalize};
pub use mesh::{holes, topology};
pub use products::samples;
pub use stages::extract::{self, close_grid};
pub use stages::refine;
