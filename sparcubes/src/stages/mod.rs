//! The conversion's stages, each a free function over plain data, in the order
//! [`crate::convert()`] runs them (numbers as in docs/ALGORITHM.md):
//!
//! 1. `normalize` — the mesh checked and fitted into the grid with a margin, in grid
//!    coordinates;
//! 2. `voxelize` — wall cells (cells a triangle touches) and grid edges a triangle crosses;
//! 3. `flood` — outside cells by a hierarchical flood fill (bricks, then cells);
//! 4. `seal` — openings small for their part sealed, so nearly closed solids stay solid;
//! 5. [`band`] — exact unsigned distance and closest point on the vertices near the surface;
//! 6. `inside` — the inside test: enclosed regions, sealed vertices and nested solids
//!    decided by the source's winding number;
//! 7. `sign` — inside/outside per vertex (`vertex_side`), thin-shell treatment of open parts;
//! 8. `deform` — φ and the bounded displacement of each vertex towards the surface;
//! 9. `ring` — the surface-free cells next to the walls a thin shell reaches, with their own
//!    band;
//! 10. `assemble` — the cells with a sign change and their corners, stored;
//! 11. [`extract`] — marching cubes over the active cells → a closed, 2-manifold mesh;
//! 12. [`refine`] (optional, the paper's step 4) — the displacements refined against
//!     renderings of the source;
//! 13. [`frame`] (with `params.output_span`) — the conversion run again with the output's box
//!     framed, and the box's ends put exactly where a consumer reading the output as filling
//!     its cube expects them.
//!
//! Only [`band`] (for the benches), [`extract`] and [`refine`] (for other crates) are public.

pub(crate) mod assemble;
pub mod band;
pub(crate) mod deform;
pub mod extract;
pub(crate) mod flood;
pub mod frame;
pub(crate) mod inside;
pub(crate) mod normalize;
pub mod refine;
pub(crate) mod ring;
pub(crate) mod seal;
pub(crate) mod sign;
pub(crate) mod vertex_side;
pub(crate) mod voxelize;
