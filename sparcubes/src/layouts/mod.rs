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

use crate::grid::cubes::SparseCubes;
use rayon::prelude::*;

/// Cells per chunk of [`cells_with_corners`]: big enough that the per-chunk binary searches
/// vanish, small enough that a chunk's table (32 bytes a cell) stays in cache.
const CHUNK: usize = 4096;

/// Offset of corner `k`: `(k & 1, k >> 1 & 1, k >> 2)`.
fn corner_offset(k: usize) -> [u16; 3] {
    let k = k as u16;
    [k & 1, (k >> 1) & 1, k >> 2]
}

/// Every cell of `cubes` (in `cubes.cells` order) with the indices in `cubes.coords` of its
/// eight corners (corner `k` at `(k & 1, k >> 1 & 1, k >> 2)`), or `None` when one is not
/// stored.
///
/// Cells and coordinates are both sorted by `(x, y, z)`, and adding one offset to every cell
/// keeps that order, so each corner is found by one forward walk through `coords` per chunk
/// of cells instead of a binary search per corner (the layouts spent most of their time in
/// those searches).
pub(crate) fn cells_with_corners(
    cubes: &SparseCubes,
) -> impl ParallelIterator<Item = ([u16; 3], Option<[usize; 8]>)> + '_ {
    cubes.cells.par_chunks(CHUNK).flat_map_iter(move |chunk| {
        let table = chunk_corners(&cubes.coords, chunk);
        chunk.iter().copied().zip(table)
    })
}

/// [`cells_with_corners`] a chunk at a time, in order: each run of cells with its corner
/// table, for layouts that build their output per chunk and join the chunks at the end.
pub(crate) fn chunks_with_corners(
    cubes: &SparseCubes,
) -> impl IndexedParallelIterator<Item = (&[[u16; 3]], Vec<Option<[usize; 8]>>)> + '_ {
    cubes
        .cells
        .par_chunks(CHUNK)
        .map(move |chunk| (chunk, chunk_corners(&cubes.coords, chunk)))
}

/// The corner indices of a sorted run of cells (see [`cells_with_corners`]).
fn chunk_corners(coords: &[[u16; 3]], cells: &[[u16; 3]]) -> Vec<Option<[usize; 8]>> {
    let mut table = vec![Some([0usize; 8]); cells.len()];
    for k in 0..8 {
        let o = corner_offset(k);
        let shifted = |c: [u16; 3]| -> Option<[u16; 3]> {
            Some([
                c[0].checked_add(o[0])?,
                c[1].checked_add(o[1])?,
                c[2].checked_add(o[2])?,
            ])
        };
        let mut j = cells
            .first()
            .and_then(|&c| shifted(c))
            .map_or(coords.len(), |v| coords.partition_point(|x| *x < v));
        for (row, &c) in table.iter_mut().zip(cells) {
            let Some(v) = shifted(c) else {
                *row = None;
                continue;
            };
            while j < coords.len() && coords[j] < v {
                j += 1;
            }
            match row {
                Some(idx) if j < coords.len() && coords[j] == v => idx[k] = j,
                _ => *row = None,
            }
        }
    }
    table
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stages::extract::sample_box;

    /// The binary-search lookup the walk replaces.
    fn corners_by_search(cubes: &SparseCubes, c: [u16; 3]) -> Option<[usize; 8]> {
        let mut idx = [0usize; 8];
        for (k, slot) in idx.iter_mut().enumerate() {
            let o = corner_offset(k);
            *slot = cubes.vertex_index([c[0] + o[0], c[1] + o[1], c[2] + o[2]])?;
        }
        Some(idx)
    }

    #[test]
    fn walk_finds_the_same_corners_as_binary_search() {
        // A sphere of radius 20: more cells than one chunk.
        let mut cubes = sample_box(64, [0; 3], [48; 3], |c| {
            let d = c.map(|v| v as f32 - 24.0);
            (
                (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - 20.0,
                [0.0; 3],
            )
        });
        assert!(cubes.cells.len() > CHUNK, "{} cells", cubes.cells.len());
        // Drop every fifth vertex so that some cells miss corners.
        let keep: Vec<usize> = (0..cubes.coords.len()).filter(|i| i % 5 != 3).collect();
        cubes.coords = keep.iter().map(|&i| cubes.coords[i]).collect();
        cubes.sdf = keep.iter().map(|&i| cubes.sdf[i]).collect();
        let walked: Vec<_> = cells_with_corners(&cubes).collect();
        assert_eq!(walked.len(), cubes.cells.len());
        let mut missing = 0;
        for (&c, (wc, idx)) in cubes.cells.iter().zip(&walked) {
            assert_eq!(c, *wc);
            assert_eq!(*idx, corners_by_search(&cubes, c), "cell {c:?}");
            missing += usize::from(idx.is_none());
        }
        assert!(
            missing > 0 && missing < walked.len(),
            "{missing} of {}",
            walked.len()
        );
    }
}
