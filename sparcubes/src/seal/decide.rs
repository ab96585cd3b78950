//! The coarse decisions of the sealing stage: which sealed pockets are solid (by the source's
//! winding number), which coarse cells of the dilated band each side takes back, and which
//! coarse cells holding surface still need the fine competition ([`super::fine`]).

use super::coarse::{CoarseGrid, Run};
use crate::regions::Sets;
use crate::regions::{median_winding, SAMPLES, SOLID_FROM};
use crate::winding::WindingTree;

/// The connected sets (through cell faces) of `set`, each as its runs in scan order (by z,
/// then y, then x), the sets ordered by their first cell. Runs of neighbouring rows that
/// overlap along x are joined (a union–find over runs), so the cost follows the rows the set
/// crosses rather than its cells.
pub fn components(set: &CoarseGrid) -> Vec<Vec<Run>> {
    joined(set, false)
}

/// The connected sets of `set` as [`components`] finds them, through faces only or (with
/// `corners`) through faces, edges and corners.
fn joined(set: &CoarseGrid, corners: bool) -> Vec<Vec<Run>> {
    let runs = set.runs();
    let side = set.side;
    // Runs of row (y, z) are runs[row_start[y + side·z]..row_start[y + side·z + 1]].
    let mut row_start = vec![0usize; side * side + 1];
    for r in &runs {
        row_start[r.y + side * r.z + 1] += 1;
    }
    for i in 0..side * side {
        row_start[i + 1] += row_start[i];
    }
    // Earlier rows a run can touch: (dy, dz) with one step back in y or z; with corners, also
    // the diagonal rows, and runs that only meet at their ends' neighbours.
    let earlier: &[(i64, i64)] = if corners {
        &[(-1, 0), (0, -1), (-1, -1), (1, -1)]
    } else {
        &[(-1, 0), (0, -1)]
    };
    let slack = corners as usize;
    let mut sets = Sets::new(runs.len());
    for (i, r) in runs.iter().enumerate() {
        for &(dy, dz) in earlier {
            let (y, z) = (r.y as i64 + dy, r.z as i64 + dz);
            if y < 0 || z < 0 || y as usize >= side {
                continue;
            }
            let other = y as usize + side * z as usize;
            for j in row_start[other]..row_start[other + 1] {
                if runs[j].x0 < r.x1 + slack && r.x0 < runs[j].x1 + slack {
                    sets.union(i as u32, j as u32);
                }
            }
        }
    }
    // Roots are the smallest (first in scan order) run of each set.
    let mut out: Vec<Vec<Run>> = Vec::new();
    let mut slot = vec![u32::MAX; runs.len()];
    for (i, r) in runs.iter().enumerate() {
        let root = sets.find(i as u32) as usize;
        if slot[root] == u32::MAX {
            slot[root] = out.len() as u32;
            out.push(Vec::new());
        }
        out[slot[root] as usize].push(*r);
    }
    out
}

/// Number of cells of a component.
pub fn cell_count(runs: &[Run]) -> usize {
    runs.iter().map(|r| r.x1 - r.x0).sum()
}

/// The `k`-th cell of a component in scan order.
fn nth_cell(runs: &[Run], mut k: usize) -> [usize; 3] {
    for r in runs {
        let len = r.x1 - r.x0;
        if k < len {
            return [r.x0 + k, r.y, r.z];
        }
        k -= len;
    }
    runs.last().map_or([0; 3], |r| [r.x1 - 1, r.y, r.z])
}

/// The median |w| of the source at up to [`SAMPLES`] cells of a component spread evenly over
/// its scan order (cell centres, in fine voxels: coarse cells are `cell` voxels wide).
pub fn component_winding(tree: &WindingTree, runs: &[Run], cell: u32) -> f64 {
    let total = cell_count(runs);
    let k = SAMPLES.min(total);
    let points: Vec<[f64; 3]> = (0..k)
        .map(|i| {
            let c = nth_cell(runs, (2 * i + 1) * total / (2 * k));
            c.map(|v| (v as f64 + 0.5) * cell as f64)
        })
        .collect();
    median_winding(tree, &points, &mut Vec::with_capacity(64))
}

/// Whether a sealed pocket reads as solid: the same threshold as an enclosed region's
/// (docs/ALGORITHM.md §2b).
pub fn is_solid(w: f64) -> bool {
    w >= SOLID_FROM
}

/// The two sides grown into `contested` cells, one face step per round, from `inside` and
/// `outside` seeds: each contested cell goes to the side that reaches it first (the nearer
/// one through contested cells), to the outside when both reach it in the same round. Beyond
/// the cube is outside, so cells on its border are reached by the outside in the first
/// round. Cells neither side reaches stay with neither. Returns (inside, outside), seeds
/// included. Each round visits only the rows that still hold contested cells.
pub fn compete(
    inside: &CoarseGrid,
    outside: &CoarseGrid,
    contested: &CoarseGrid,
) -> (CoarseGrid, CoarseGrid) {
    let (mut inside, mut outside) = (inside.clone(), outside.clone());
    let mut open = contested.and_not(&inside).and_not(&outside);
    let (side, w) = (open.side, open.words());
    let mut rows = open.rows_with_cells();
    let (mut reach_in, mut reach_out, mut beyond) = (vec![0u64; w], vec![0u64; w], vec![0u64; w]);
    let mut first = true;
    loop {
        let mut taken: Vec<(usize, usize, Vec<u64>, Vec<u64>)> = Vec::new();
        for &(y, z) in &rows {
            let open_row = open.row_words(y, z);
            inside.grown_row(y, z, &mut reach_in);
            outside.grown_row(y, z, &mut reach_out);
            if first {
                CoarseGrid::border_row(side, y, z, &mut beyond);
                reach_out.iter_mut().zip(&beyond).for_each(|(o, b)| *o |= b);
            }
            let to_out: Vec<u64> = (0..w).map(|i| reach_out[i] & open_row[i]).collect();
            let to_in: Vec<u64> = (0..w)
                .map(|i| reach_in[i] & open_row[i] & !to_out[i])
                .collect();
            if to_out.iter().chain(&to_in).any(|&b| b != 0) {
                taken.push((y, z, to_in, to_out));
            }
        }
        if taken.is_empty() {
            return (inside, outside);
        }
        for (y, z, to_in, to_out) in &taken {
            inside.or_row(*y, *z, to_in);
            outside.or_row(*y, *z, to_out);
            open.clear_row(*y, *z, to_in);
            open.clear_row(*y, *z, to_out);
        }
        rows.retain(|&(y, z)| open.row_words(y, z).iter().any(|&b| b != 0));
        first = false;
    }
}

/// The cells of `holding` (coarse cells with surface, or left to neither side) joined to a
/// cell next to `inside` (one of its 26 neighbours) through cells of `holding` sharing a face,
/// an edge or a corner: where the fine competition must decide cell by cell.
pub fn near_inside(holding: &CoarseGrid, inside: &CoarseGrid) -> CoarseGrid {
    let touching = inside.dilate(1);
    let mut found = CoarseGrid::new(holding.side);
    for runs in joined(holding, true) {
        let near = runs
            .iter()
            .any(|r| (r.x0..r.x1).any(|x| touching.get([x, r.y, r.z].map(|v| v as i64))));
        if near {
            runs.iter().for_each(|r| found.set_run(r));
        }
    }
    found
}
#[cfg(test)]
mod tests {
    use super::*;

    fn line(side: usize, xs: std::ops::Range<usize>) -> CoarseGrid {
        let mut g = CoarseGrid::new(side);
        for x in xs {
            g.set([x, 3, 3]);
        }
        g
    }

    #[test]
    fn components_split_where_faces_do_not_touch() {
        let mut g = line(10, 0..3);
        g.set([5, 3, 3]);
        g.set([6, 4, 4]); // touches (5, 3, 3) only along an edge
        g.set([2, 4, 3]); // joined to the first run through a face
        g.set([2, 4, 4]);
        let comps = components(&g);
        assert_eq!(comps.len(), 3);
        assert_eq!(cell_count(&comps[0]), 5);
        assert_eq!(nth_cell(&comps[0], 3), [2, 4, 3]);
        assert_eq!(
            comps[1],
            vec![Run {
                y: 3,
                z: 3,
                x0: 5,
                x1: 6
            }]
        );
    }

    #[test]
    fn components_join_runs_through_later_rows() {
        // A U: two columns joined only at the top row, reached after both are seen.
        let mut g = CoarseGrid::new(8);
        for y in 0..4 {
            g.set([1, y, 2]);
            g.set([5, y, 2]);
        }
        for x in 1..6 {
            g.set([x, 4, 2]);
        }
        let comps = components(&g);
        assert_eq!(comps.len(), 1);
        assert_eq!(cell_count(&comps[0]), 13);
    }

    #[test]
    fn competition_splits_a_corridor_at_its_middle_and_gives_ties_to_the_outside() {
        // Seeds at x = 0 (inside) and x = 9 (outside), contested cells 1..=8: each side
        // takes its nearer half. With the outside seed at x = 8, both reach x = 4 in the same
        // round, and it goes outside.
        let contested = line(12, 1..9);
        let (inside, outside) = compete(&line(12, 0..1), &line(12, 9..10), &contested);
        assert_eq!(inside, line(12, 0..5));
        assert_eq!(outside, line(12, 5..10));
        let contested = line(12, 1..8);
        let (inside, outside) = compete(&line(12, 0..1), &line(12, 8..9), &contested);
        assert_eq!(inside, line(12, 0..4));
        assert_eq!(outside, line(12, 4..9), "the tie at x = 4 goes outside");
    }

    #[test]
    fn near_inside_follows_holding_cells_through_corners() {
        let inside = line(12, 0..1);
        let mut holding = CoarseGrid::new(12);
        holding.set([1, 4, 4]); // a corner away from (0, 3, 3)
        holding.set([2, 5, 5]); // a corner away from the previous
        holding.set([6, 5, 5]); // not joined
        let near = near_inside(&holding, &inside);
        assert_eq!(near.count(), 2);
        assert!(near.get([2, 5, 5]) && !near.get([6, 5, 5]));
    }
}
