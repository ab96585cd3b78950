//! What other crates build on, computed from one item's sparse cubes and the mesh extracted
//! from them, and named for what it computes (who reads it, and in which layout, is
//! `sparc3d-formats`' business):
//!
//! - [`samples`] — point samples of the output with exact signed distances and occupancy.
//! - [`corners`] — every active cell's eight corners among the stored vertices, and their φ.
//! - [`dual_vertices`] — a dual vertex per active cell and the crossed edges at its upper
//!   corner.
//! - [`truncated_sdf`] — the grid points within a band of the surface with their signed
//!   distance over the band's width.
//! - [`shape_signature`] — a fixed-length vector of the output's shape, the same whatever
//!   rigid motion, uniform scale, mirroring or triangulation, for finding near-duplicates.
//!
//! Everything is in the item's grid (resolution N, the job's normalization) and the same
//! whatever the thread count.

pub mod corners;
pub mod dual_vertices;
pub mod samples;
pub mod shape_signature;
pub mod truncated_sdf;
