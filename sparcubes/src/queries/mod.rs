//! Questions asked of a mesh or of the output grid, answered exactly and the same whatever the
//! thread count.
//!
//! - [`closest`] — the closest point of a mesh to each point of a batch (a 4-wide BVH over the
//!   triangles in Morton order), and the side of a point from its closest face where that is
//!   exact.
//! - [`winding`] — the generalised winding number of a triangle soup, hierarchically: the
//!   inside test of the conversion.
//! - [`sides`] — inside or outside of the watertight output, read from the sparse grid alone.

pub mod closest;
pub mod sides;
pub mod winding;
