//! The fine competition of the sealing stage: inside the coarse cells that hold surface next
//! to a sealed pocket, which fine cells the pocket takes and which stay outside.
//!
//! The same rule as the coarse competition ([`super::decide::compete`]), cell by cell: the
//! pocket's cells and the outside's cells grow one face step per round into the contested
//! cells, each cell going to the side that reaches it first through free cells (to the
//! outside on a tie). On the outer side of a wall the outside is nearer, on its inner side the
//! pocket; in an opening the two meet about halfway, where the cap will be. Bit-parallel over
//! 8³ bricks, a round reading the previous round's masks, so the result does not depend on
//! the order or the thread count.

use super::coarse::CoarseGrid;
use crate::grid::BrickIndex;
use crate::grid::{face_carry, or_assign, shift, BrickMask, BrickSet, BRICK};
use crate::stages::flood::{Flood, DIRS, FULL};
use rayon::prelude::*;
use std::collections::HashMap;

/// The fine cells of a brick that lie in cells of a coarse set (coarse cells of `cell` fine
/// cells per axis, a power of two).
pub fn coarse_mask(grid: &CoarseGrid, b: [u32; 3], cell: u32) -> BrickMask {
    let origin = b.map(|v| (v * BRICK) as i64);
    if cell >= BRICK {
        return if grid.get(origin.map(|v| v / cell as i64)) {
            FULL
        } else {
            [0; 8]
        };
    }
    // Each coarse row the brick crosses gives `per` bits along x, each widened to `cell` fine
    // bits: one byte of a brick row, for the `cell` fine rows and planes it covers.
    let (c, per) = (cell as usize, (BRICK / cell) as usize);
    let corner = origin.map(|v| v as usize / c);
    let mut mask = [0u64; 8];
    for cz in 0..per {
        for cy in 0..per {
            let bits = grid.row_bits(corner[0], corner[1] + cy, corner[2] + cz, per);
            if bits == 0 {
                continue;
            }
            let byte = (0..8).fold(0u64, |b, x| b | ((bits >> (x / c)) & 1) << x);
            let rows = (cy * c..(cy + 1) * c).fold(0u64, |r, y| r | byte << (8 * y));
            for word in &mut mask[cz * c..(cz + 1) * c] {
                *word |= rows;
            }
        }
    }
    mask
}

/// The fine bricks that overlap cells of a coarse set (coarse cells of `cell` fine cells per
/// axis), by key (ascending). Run by run: a run of coarse cells covers a run of bricks.
pub fn bricks_of(grid: &CoarseGrid, index: &BrickIndex, cell: u32) -> Vec<u32> {
    let mut keys = Vec::new();
    for r in grid.runs() {
        let lo = [r.x0, r.y, r.z].map(|v| v as u32 * cell / BRICK);
        let top = [r.x1 - 1, r.y, r.z].map(|v| (v as u32 + 1) * cell);
        let hi: [u32; 3] = std::array::from_fn(|a| top[a].div_ceil(BRICK).max(lo[a] + 1));
        for bz in lo[2]..hi[2].min(index.dims[2]) {
            for by in lo[1]..hi[1].min(index.dims[1]) {
                for bx in lo[0]..hi[0].min(index.dims[0]) {
                    keys.push(index.key([bx, by, bz]) as u32);
                }
            }
        }
    }
    keys.sort_unstable();
    keys.dedup();
    keys
}

/// One brick's state in the competition.
#[derive(Debug, Clone, Copy)]
struct Sides {
    /// Cells still to be decided (free, reached by the exact flood, in a contested coarse cell).
    open: BrickMask,
    /// Cells the pocket holds.
    inside: BrickMask,
    /// Free cells the outside holds.
    outside: BrickMask,
}

/// The cells the pocket (`inside`, coarse) takes in the fine bricks of the contested coarse
/// cells `contested`, per brick key (ascending), seeds included. A brick's free cells
/// reached by the exact flood (`flood` over `walls`) are the pocket's seeds where their coarse
/// cell is in `inside`, contested where it is in `contested`, and the outside's seeds
/// elsewhere; beyond the brick space is outside.
pub fn compete_fine(
    walls: &BrickSet,
    flood: &Flood,
    inside: &CoarseGrid,
    contested: &CoarseGrid,
    cell: u32,
) -> Vec<(u32, BrickMask)> {
    let index = &walls.index;
    let keys = bricks_of(contested, index, cell);
    let sides_of = |key: u32| -> Sides {
        let b = index.coord(key as usize);
        let free = flood.outside_cells(walls, key as usize);
        let pocket = coarse_mask(inside, b, cell);
        let open = coarse_mask(contested, b, cell);
        Sides {
            open: std::array::from_fn(|z| free[z] & open[z] & !pocket[z]),
            inside: std::array::from_fn(|z| free[z] & pocket[z]),
            outside: std::array::from_fn(|z| free[z] & !pocket[z] & !open[z]),
        }
    };
    // Every brick the competition reads: the contested ones, then their face neighbours.
    let mut table: Vec<Sides> = keys.par_iter().map(|&k| sides_of(k)).collect();
    let mut slot: HashMap<u32, u32> = keys
        .iter()
        .enumerate()
        .map(|(i, &k)| (k, i as u32))
        .collect();
    let mut neighbours: Vec<[Option<u32>; 6]> = Vec::with_capacity(keys.len());
    for &k in &keys {
        let b = index.coord(k as usize);
        let mut near = [None; 6];
        for (d, (axis, high)) in DIRS.into_iter().enumerate() {
            let mut q = b.map(|v| v as i64);
            q[axis] += if high { 1 } else { -1 };
            if (0..3).any(|a| q[a] < 0 || q[a] >= index.dims[a] as i64) {
                continue;
            }
            let qk = index.key(q.map(|v| v as u32)) as u32;
            let s = *slot.entry(qk).or_insert_with(|| {
                table.push(sides_of(qk));
                (table.len() - 1) as u32
            });
            near[d] = Some(s);
        }
        neighbours.push(near);
    }
    let mut active: Vec<u32> = (0..keys.len() as u32).collect();
    while !active.is_empty() {
        let grown: Vec<(u32, BrickMask, BrickMask)> = active
            .par_iter()
            .filter_map(|&i| {
                let (to_in, to_out) = round(&table, &neighbours[i as usize], i as usize);
                (to_in != [0; 8] || to_out != [0; 8]).then_some((i, to_in, to_out))
            })
            .collect();
        let mut next = Vec::new();
        for &(i, to_in, to_out) in &grown {
            let s = &mut table[i as usize];
            or_assign(&mut s.inside, &to_in);
            or_assign(&mut s.outside, &to_out);
            for z in 0..8 {
                s.open[z] &= !(to_in[z] | to_out[z]);
            }
            next.push(i);
            next.extend(
                neighbours[i as usize]
                    .iter()
                    .flatten()
                    .filter(|&&j| (j as usize) < keys.len()),
            );
        }
        next.sort_unstable();
        next.dedup();
        active = next;
    }
    keys.iter()
        .zip(&table)
        .map(|(&k, s)| (k, s.inside))
        .filter(|(_, m)| *m != [0; 8])
        .collect()
}

/// One round for brick `i`: the open cells each side reaches with one face step from the
/// previous round's cells (its own and its neighbours'), ties to the outside.
fn round(table: &[Sides], near: &[Option<u32>; 6], i: usize) -> (BrickMask, BrickMask) {
    let me = &table[i];
    if me.open == [0; 8] {
        return ([0; 8], [0; 8]);
    }
    let mut reach_in = [0u64; 8];
    let mut reach_out = [0u64; 8];
    for (d, (axis, high)) in DIRS.into_iter().enumerate() {
        or_assign(&mut reach_in, &shift(&me.inside, axis, high));
        or_assign(&mut reach_out, &shift(&me.outside, axis, high));
        // What the neighbour on side (axis, high) carries across its face into this brick.
        match near[d] {
            Some(j) => {
                let other = &table[j as usize];
                or_assign(&mut reach_in, &face_carry(&other.inside, axis, !high));
                or_assign(&mut reach_out, &face_carry(&other.outside, axis, !high));
            }
            None => or_assign(&mut reach_out, &face_carry(&FULL, axis, !high)),
        }
    }
    let to_out: BrickMask = std::array::from_fn(|z| reach_out[z] & me.open[z]);
    let to_in: BrickMask = std::array::from_fn(|z| reach_in[z] & me.open[z] & !to_out[z]);
    (to_in, to_out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::test;

    #[test]
    fn coarse_masks_hold_the_fine_cells_of_coarse_cells() {
        for cell in [1u32, 2, 4, 8, 16] {
            let side = (64 / cell) as usize;
            let mut grid = CoarseGrid::new(side);
            for i in 0..40usize {
                grid.set([(i * 7) % side, (i * 11) % side, (i * 5) % side]);
            }
            for b in [[0u32, 0, 0], [1, 2, 3], [7, 7, 7], [3, 0, 5]] {
                let mask = coarse_mask(&grid, b, cell);
                for z in 0..8u32 {
                    for y in 0..8u32 {
                        for x in 0..8u32 {
                            let fine = [b[0] * 8 + x, b[1] * 8 + y, b[2] * 8 + z];
                            let want = grid.get(fine.map(|v| (v / cell) as i64));
                            let got = test(&mask, z as usize, x + 8 * y);
                            assert_eq!(got, want, "cell {cell} brick {b:?} at {fine:?}");
                        }
                    }
                }
            }
        }
    }
}
