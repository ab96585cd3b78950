//! The conversion's stages, each a free function over plain data, in the order
//! [`crate::convert()`] runs them (docs/ALGORITHM.md).

pub(crate) mod assemble;
pub mod band;
pub(crate) mod deform;
pub mod extract;
pub(crate) mod flood;
pub(crate) mod inside;
pub(crate) mod normalize;
pub mod refine;
pub(crate) mod ring;
pub(crate) mod seal;
pub(crate) mod sign;
pub(crate) mod vertex_side;
pub(crate) mod voxelize;
