//! Writing a sealing's result into the flood, and finding the cells its caps run through.

use super::coarse::CoarseGrid;
use super::fine::{bricks_of, coarse_mask};
use crate::grid::{face_carry, shift, BrickIndex, BrickMask, BrickSet, NO_BRICK};
use crate::stages::flood::{Flood, FULL};
use crate::stages::voxelize::Voxelization;
use rayon::prelude::*;

/// Every fine cell a sealed pocket takes, per brick key (ascending): the free cells the
/// exact flood reached in the pocket's coarse cells (`inside`), and in the contested bricks
/// what the fine competition gave it (`won`, which includes those seeds).
pub fn sealed_cells(
    walls: &BrickSet,
    flood: &Flood,
    inside: &CoarseGrid,
    won: Vec<(u32, BrickMask)>,
    cell: u32,
) -> Vec<(u32, BrickMask)> {
    let index = &walls.index;
    let keys = bricks_of(inside, index, cell);
    let cells: Vec<(u32, BrickMask)> = keys
        .par_iter()
        .map(|&k| {
            let free = flood.outside_cells(walls, k as usize);
            let pocket = coarse_mask(inside, index.coord(k as usize), cell);
            (k, std::array::from_fn(|z| free[z] & pocket[z]))
        })
        .collect();
    // The competition's answer wins in its bricks (both lists are sorted by key).
    let mut merged = Vec::with_capacity(cells.len() + won.len());
    let mut won = won.into_iter().peekable();
    for (k, m) in cells {
        while let Some(w) = won.next_if(|w| w.0 < k) {
            merged.push(w);
        }
        match won.next_if(|w| w.0 == k) {
            Some(w) => merged.push(w),
            None => merged.push((k, m)),
        }
    }
    merged.extend(won);
    merged.retain(|(_, m)| *m != [0; 8]);
    merged
}

/// Takes the sealed cells out of the flood's outside. An empty brick (no wall cell) split by
/// a cap becomes a wall brick with no wall cell, so that the flood can hold its outside cell
/// by cell; the walls' members do not change.
pub fn apply(vox: &mut Voxelization, flood: &mut Flood, sealed: &[(u32, BrickMask)], n: u32) {
    let mut split: Vec<(u32, BrickMask)> = Vec::new();
    for &(key, m) in sealed {
        match vox.walls.index.slots[key as usize] {
            NO_BRICK if m == FULL => flood.empty_outside[key as usize] = false,
            NO_BRICK => {
                flood.empty_outside[key as usize] = false;
                split.push((key, std::array::from_fn(|z| !m[z])));
            }
            s => {
                let out = &mut flood.wall_outside[s as usize];
                for z in 0..8 {
                    out[z] &= !m[z];
                }
            }
        }
    }
    if split.is_empty() {
        return;
    }
    let walls = &vox.walls;
    let mut merged: Vec<(u32, BrickMask, BrickMask)> = walls
        .keys
        .iter()
        .zip(&walls.masks)
        .zip(&flood.wall_outside)
        .map(|((&k, &w), &o)| (k, w, o))
        .chain(split.into_iter().map(|(k, o)| (k, [0; 8], o)))
        .collect();
    merged.sort_unstable_by_key(|e| e.0);
    let keys: Vec<u32> = merged.iter().map(|e| e.0).collect();
    vox.walls = BrickSet {
        index: BrickIndex::with_keys(n, &keys),
        masks: merged.iter().map(|e| e.1).collect(),
        keys,
    };
    flood.wall_outside = merged.into_iter().map(|e| e.2).collect();
}

/// The sealed cells with an outside cell among their 26 neighbours, per brick key
/// (ascending): the cells a cap runs through, searched in the bricks `near` (those of the
/// coarse cells where the pocket meets anything but itself). Read after [`apply`].
pub fn cap_cells(
    walls: &BrickSet,
    flood: &Flood,
    sealed: &[(u32, BrickMask)],
    near: &[u32],
) -> Vec<(u32, BrickMask)> {
    near.par_iter()
        .filter_map(|&k| {
            let i = sealed.binary_search_by_key(&k, |e| e.0).ok()?;
            let grown = outside_grown(walls, flood, walls.index.coord(k as usize));
            let m = &sealed[i].1;
            let cap: BrickMask = std::array::from_fn(|z| m[z] & grown[z]);
            (cap != [0; 8]).then_some((k, cap))
        })
        .collect()
}

/// The outside cells of the brick at `b` and its 26 neighbours grown by one cell along every
/// axis both ways (the 26-neighbourhood), as seen in brick `b`. Beyond the brick space is
/// outside.
fn outside_grown(walls: &BrickSet, flood: &Flood, b: [u32; 3]) -> BrickMask {
    let index = &walls.index;
    let at = |d: [i64; 3]| -> BrickMask {
        let q: [i64; 3] = std::array::from_fn(|a| b[a] as i64 + d[a]);
        if (0..3).any(|a| q[a] < 0 || q[a] >= index.dims[a] as i64) {
            return FULL;
        }
        flood.outside_cells(walls, index.key(q.map(|v| v as u32)))
    };
    // Separably: along x for the 3×3 bricks around (y, z), then along y, then along z.
    let grow = |m: BrickMask, low: BrickMask, high: BrickMask, axis: usize| -> BrickMask {
        let (up, down) = (shift(&m, axis, true), shift(&m, axis, false));
        let (from_low, from_high) = (face_carry(&low, axis, true), face_carry(&high, axis, false));
        std::array::from_fn(|z| m[z] | up[z] | down[z] | from_low[z] | from_high[z])
    };
    let along_x = |dy: i64, dz: i64| grow(at([0, dy, dz]), at([-1, dy, dz]), at([1, dy, dz]), 0);
    let along_y = |dz: i64| grow(along_x(0, dz), along_x(-1, dz), along_x(1, dz), 1);
    grow(along_y(0), along_y(-1), along_y(1), 2)
}
