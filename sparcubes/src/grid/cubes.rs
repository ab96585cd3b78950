//! The output of a conversion: the sparse cube grid with SDF and deformation per active
//! vertex. This is what shard rows store; [`crate::extract()`] turns it into a mesh.

use crate::grid::normalization::Normalization;

/// A sparse cube grid at resolution N (grid vertices `0..=N` per axis).
///
/// Invariants: `coords` is sorted by `(x, y, z)` lexicographically and unique; `sdf` and
/// `deformation` are parallel to it; `cells` (min corners) is sorted the same way, and every
/// corner of every cell is in `coords`. Each cell has a sign change among its corners.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SparseCubes {
    /// Cells per axis.
    pub resolution: u32,
    /// Map between the source frame and the unit cube.
    pub normalization: Normalization,
    /// Active grid vertices, sorted.
    pub coords: Vec<[u16; 3]>,
    /// Signed distance at each (deformed) vertex, in voxels; negative inside.
    pub sdf: Vec<f32>,
    /// Displacement of each vertex, in voxels: its position is `coords + deformation`.
    pub deformation: Vec<[f32; 3]>,
    /// Active cells by their minimum corner, sorted.
    pub cells: Vec<[u16; 3]>,
}

impl SparseCubes {
    /// Index of the vertex at `c` in `coords`, by binary search.
    pub fn vertex_index(&self, c: [u16; 3]) -> Option<usize> {
        self.coords.binary_search(&c).ok()
    }
}

/// Index of the first of the sorted `coords` that is `>= target`, at or after `from`, by
/// galloping: a walk through rising targets costs the logarithm of each step, not of the
/// whole list.
#[inline]
pub(crate) fn gallop<T: Ord>(coords: &[T], from: usize, target: T) -> usize {
    if from >= coords.len() || coords[from] >= target {
        return from;
    }
    let mut step = 1;
    let mut lo = from;
    while lo + step < coords.len() && coords[lo + step] < target {
        lo += step;
        step *= 2;
    }
    let hi = (lo + step + 1).min(coords.len());
    lo + coords[lo..hi].partition_point(|c| *c < target)
}
