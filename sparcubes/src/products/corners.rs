//! The corners of the active cells: for every cell its eight corners' indices among the
//! stored vertices, found by one forward walk per chunk of cells ([`cells_with_corners`]),
//! and their φ ([`corner_values`]).

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
/// of cells instead of a binary search per corner (the products built on it spent most of
/// their time in those searches).
pub fn cells_with_corners(
    cubes: &SparseCubes,
) -> impl ParallelIterator<Item = ([u16; 3], Option<[usize; 8]>)> + '_ {
    cubes.cells.par_chunks(CHUNK).flat_map_iter(move |chunk| {
        let table = chunk_corners(&cubes.coords, chunk);
        chunk.iter().copied().zip(table)
    })
}

/// [`cells_with_corners`] a chunk at a time, in order: each run of cells with its corner
/// table, for products that build their output per chunk and join the chunks at the end.
pub fn chunks_with_corners(
    cubes: &SparseCubes,
) -> impl IndexedParallelIterator<Item = (&[[u16; 3]], Vec<Option<[usize; 8]>>)> + '_ {
    cubes
        .cells
        .par_chunks(CHUNK)
        .map(move |chunk| (chunk, chunk_corners(&cubes.coords, chunk)))
}

/// The eight corner values of each active cell.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CornerValues {
    /// Active cells by minimum corner, sorted.
    pub cells: Vec<[u16; 3]>,
    /// Per cell, φ at corner `k` (at `(k & 1, k >> 1 & 1, k >> 2)`), in voxels.
    pub values: Vec<[f32; 8]>,
}

/// φ at the eight corners of every cell of `cubes` (cells whose corners are not all stored are
/// skipped).
pub fn corner_values(cubes: &SparseCubes) -> CornerValues {
    let (cells, values) = cells_with_corners(cubes)
        .filter_map(|(c, idx)| Some((c, idx?.map(|i| cubes.sdf[i]))))
        .unzip();
    CornerValues { cells, values }
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

    #[test]
    fn corner_values_are_phi_at_the_corners_in_bit_order() {
        // A plane x = 2.3: φ = x − 2.3 at every vertex.
        let cubes = sample_box(8, [0; 3], [6; 3], |c| (c[0] as f32 - 2.3, [0.0; 3]));
        let v = corner_values(&cubes);
        assert_eq!(v.cells, cubes.cells);
        assert_eq!(v.cells.len(), 36);
        for (c, values) in v.cells.iter().zip(&v.values) {
            for (k, &phi) in values.iter().enumerate() {
                let o = corner_offset(k);
                let at = [c[0] + o[0], c[1] + o[1], c[2] + o[2]];
                let stored = cubes.vertex_index(at).map(|i| cubes.sdf[i]);
                assert_eq!(Some(phi), stored, "cell {c:?} corner {k}");
            }
        }
    }
}
