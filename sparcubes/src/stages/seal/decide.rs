//! The coarse decisions of the sealing stage: which sealed pockets are solid (by the source's
//! winding number), which coarse cells of the dilated band each side takes back, and which
//! coarse cells holding surface still need the fine competition ([`super::fine`]).

use super::coarse::{CoarseGrid, Run};
use crate::queries::winding::WindingTree;
use crate::stages::inside::vote::{median_winding, SAMPLES, SOLID_FROM};
use crate::union_find::Sets;

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
/// (docs/ALGORITHM.md §6).
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
    let mut first = true;
    loop {
        // Rows are at most 4 words: the coarse grid has at most 256 cells a side.
        let mut taken: Vec<(usize, usize, Row, Row)> = Vec::new();
        for &(y, z) in &rows {
            let (mut reach_in, mut reach_out) = (Row::default(), Row::default());
            inside.grown_row(y, z, &mut reach_in[..w]);
            outside.grown_row(y, z, &mut reach_out[..w]);
            if first {
                let mut beyond = Row::default();
                CoarseGrid::border_row(side, y, z, &mut beyond[..w]);
                reach_out.iter_mut().zip(&beyond).for_each(|(o, b)| *o |= b);
            }
            let open_row = open.row_words(y, z);
            let to_out: Row =
                std::array::from_fn(|i| if i < w { reach_out[i] & open_row[i] } else { 0 });
            let to_in: Row = std::array::from_fn(|i| {
                if i < w {
                    reach_in[i] & open_row[i] & !to_out[i]
                } else {
                    0
                }
            });
            if to_out.iter().chain(&to_in).any(|&b| b != 0) {
                taken.push((y, z, to_in, to_out));
            }
        }
        if taken.is_empty() {
            return (inside, outside);
        }
        for (y, z, to_in, to_out) in &taken {
            inside.or_row(*y, *z, &to_in[..w]);
            outside.or_row(*y, *z, &to_out[..w]);
            open.clear_row(*y, *z, &to_in[..w]);
            open.clear_row(*y, *z, &to_out[..w]);
        }
        rows.retain(|&(y, z)| open.row_words(y, z).iter().any(|&b| b != 0));
        first = false;
    }
}

/// One row of a coarse grid's words (at most 256 cells).
type Row = [u64; 4];

/// Largest share of a sealed region's boundary (coarse cell faces) that may lie across its
/// openings (faces towards the outside rather than towards a wall). A nearly closed part is
/// mostly wall: a sphere with a hole 1/15 of its diameter across has 0.1 % of its boundary
/// in the hole (the sealed regions of the dev corpus at 256³ measured 0–1.0 %). A region
/// bounded largely by openings is space that the grown walls closed between parts rather
/// than a part with holes: under the seat of `sh3d-KatorLegaz__scooter__scooter.obj`, between
/// the body's panels and the engine below them, 9.9 % of the boundary was caps, and sealing
/// it cost 2.2 F1 points at 256³ (docs/QUALITY.md, issue 26).
pub const CAP_SHARE: f64 = 0.05;

/// The coarse competition of [`compete`] between the solid `pockets` and every other
/// surface-free cell (`others`) for the grown walls' cells (`band`), after leaving out the
/// pockets whose sealed region has more than [`CAP_SHARE`] of its boundary on openings:
/// regions are found and measured, the pockets in the ones that fail go to the outside, and
/// the competition runs again until every region passes (leaving pockets out can only open
/// more of the others' boundary). Returns (inside, outside, which pockets are kept).
pub fn give_back(
    pockets: &[Vec<Run>],
    others: &CoarseGrid,
    band: &CoarseGrid,
    walls: &CoarseGrid,
) -> (CoarseGrid, CoarseGrid, Vec<bool>) {
    let mut kept = vec![true; pockets.len()];
    loop {
        let side = others.side;
        let pick = |keep: bool| pockets.iter().zip(&kept).filter(move |(_, &k)| k == keep);
        let seeds = CoarseGrid::of_runs(side, pick(true).flat_map(|(runs, _)| runs));
        let rest = others.or(&CoarseGrid::of_runs(
            side,
            pick(false).flat_map(|(runs, _)| runs),
        ));
        let (inside, outside) = compete(&seeds, &rest, band);
        let mut dropped = false;
        for region in components(&inside) {
            let (cap, wall) = (outside.faces_with(&region), walls.faces_with(&region));
            if cap as f64 <= CAP_SHARE * (cap + wall) as f64 {
                continue;
            }
            for (runs, k) in pockets.iter().zip(kept.iter_mut()) {
                let r = &runs[0];
                if *k && contains(&region, [r.x0, r.y, r.z]) {
                    *k = false;
                    dropped = true;
                }
            }
        }
        if !dropped {
            return (inside, outside, kept);
        }
    }
}

/// Whether cell `c` lies in one of `runs` (in scan order).
fn contains(runs: &[Run], c: [usize; 3]) -> bool {
    let at = runs.partition_point(|r| (r.z, r.y, r.x1) <= (c[2], c[1], c[0]));
    runs.get(at)
        .is_some_and(|r| r.z == c[2] && r.y == c[1] && r.x0 <= c[0])
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
    fn a_region_mostly_bounded_by_openings_is_given_to_the_outside() {
        // A pocket in a box of walls (side 6) whose top face is open over a `hole` square: a
        // hole of one cell is 1/36 of the top, 1/216 of the boundary (kept); with the top
        // gone entirely a sixth of the boundary is opening (given back to the outside).
        for (hole, kept) in [(1usize, 1usize), (6, 0)] {
            let side = 12;
            let mut walls = CoarseGrid::new(side);
            for z in 2..10 {
                for y in 2..10 {
                    for x in 2..10 {
                        let shell = [x, y, z].iter().any(|&v| v == 2 || v == 9);
                        let centre = (x as i64 - 5).abs().max((y as i64 - 5).abs());
                        let open = z == 9 && (centre as usize) * 2 < hole;
                        if shell && !open {
                            walls.set([x, y, z]);
                        }
                    }
                }
            }
            let mut pocket = CoarseGrid::new(side);
            pocket.set([5, 5, 5]);
            let band = walls.complement().and_not(&pocket);
            let pockets = components(&pocket);
            let (inside, _, flags) = give_back(&pockets, &CoarseGrid::new(side), &band, &walls);
            assert_eq!(flags.iter().filter(|&&k| k).count(), kept, "hole {hole}");
            assert_eq!(inside.get([5, 5, 5]), kept == 1);
        }
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
