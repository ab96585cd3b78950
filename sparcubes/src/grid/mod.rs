//! The grid's data: where things are, not what is done with them.
//!
//! - [`bricks`] — the sparse storage every stage works on: bricks of 8³ cells or vertices
//!   with a 512-bit mask, behind a dense brick index; sets of bricks, their dilation, masks
//!   and numbering (its items are this room's own: `grid::BrickSet` is `grid::bricks::BrickSet`).
//! - [`morton`] — Morton (Z-order) codes of cells, by which the query trees sort triangles.
//! - [`normalization`] — the map between the source frame and the grid, and the extents a
//!   mesh may have.
//! - [`cubes`] — [`SparseCubes`](cubes::SparseCubes), the conversion's output.

pub mod bricks;
pub mod cubes;
pub mod morton;
pub mod normalization;

pub use bricks::*;
