//! The sparse layouts other model families train on, computed from one item's stored sparse
//! cubes (no second conversion):
//!
//! - [`direct3d_s2`]: Direct3D-S2's sparse SDF, grid vertices within a truncation band with
//!   their signed distance scaled to [−1, 1];
//! - [`trellis2`]: TRELLIS.2's flexible dual grid, per active voxel a dual vertex quantised to
//!   3 × `u8` and three "intersected" flags;
//! - [`cubvh`]: cubvh's sparse voxels, the 8 corner values of each active cell as sign +
//!   magnitude bytes.
//!
//! Our own tensors (`coords`, `sdf`, `deformation`, `cells`) are the fourth layout. Every
//! layout is in the item's grid (resolution N, the job's normalization).

pub mod cubvh;
pub mod direct3d_s2;
pub mod trellis2;

use crate::cubes::SparseCubes;

/// Indices in `cubes.coords` of the eight corners of cell `c` (corner `k` at
/// `(k & 1, k >> 1 & 1, k >> 2)`), or `None` when one is not stored.
pub(crate) fn cell_corners(cubes: &SparseCubes, c: [u16; 3]) -> Option<[usize; 8]> {
    let mut idx = [0usize; 8];
    for (k, slot) in idx.iter_mut().enumerate() {
        let k = k as u16;
        let v = [
            c[0].checked_add(k & 1)?,
            c[1].checked_add((k >> 1) & 1)?,
            c[2].checked_add(k >> 2)?,
        ];
        *slot = cubes.vertex_index(v)?;
    }
    Some(idx)
}
