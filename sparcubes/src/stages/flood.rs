//! Stage 3: which cells are outside. A flood fill from the grid's border over cells the
//! surface does not touch, hierarchical as in OpenVDB's signed flood fill: whole empty bricks
//! are flooded at once, and inside bricks that hold wall cells the flood advances with
//! bit-parallel dilations of 512-bit masks. Cells it never reaches are inside.

use crate::grid::{face_carry, or_assign, shift, split, test, BrickMask, BrickSet, NO_BRICK};
use rayon::prelude::*;

/// The flood's result: outside flags for empty bricks and outside masks for wall bricks.
#[derive(Debug, Clone)]
pub struct Flood {
    /// Per brick key: whether an empty brick (one without wall cells) is outside.
    pub empty_outside: Vec<bool>,
    /// Per wall brick (parallel to `walls.masks`): its outside cells.
    pub wall_outside: Vec<BrickMask>,
}

/// A brick mask with every bit set.
pub const FULL: BrickMask = [u64::MAX; 8];
/// The six face directions (axis, towards +), the order every face-step loop uses.
pub const DIRS: [(usize, bool); 6] = [
    (0, false),
    (0, true),
    (1, false),
    (1, true),
    (2, false),
    (2, true),
];

/// Grows `out` by 6-connected steps within the brick until it stops, never into `wall`.
pub fn grow_within(out: &mut BrickMask, wall: &BrickMask) {
    loop {
        let mut grown = *out;
        for (axis, plus) in DIRS {
            or_assign(&mut grown, &shift(out, axis, plus));
        }
        for z in 0..8 {
            grown[z] &= !wall[z];
        }
        if grown == *out {
            return;
        }
        *out = grown;
    }
}

/// Floods the outside over non-wall cells, starting from every cell on the border of the
/// brick space. The result is the unique least fixpoint, so it does not depend on order or on
/// the thread count.
///
/// In rounds: empty bricks (most of the grid) are flooded from a stack over a padded byte grid
/// of brick states (no bounds checks, no face masks, 1 byte a brick), one thread; then every
/// wall brick that may gain outside cells (a neighbour grew or became outside) pulls the faces
/// of its six neighbours and grows within its walls, all of them in parallel from the same
/// snapshot, and the bricks the growth reaches are the next round's. Each round only adds cells
/// the outside reaches, and it ends when nothing changes: the least fixpoint.
pub fn flood_outside(walls: &BrickSet) -> Flood {
    // One entry into the thread pool for the whole flood: its rounds (many where the outside
    // travels from wall brick to wall brick) then split their work among the pool's threads
    // without handing each round over from the calling thread and waiting for it to return.
    rayon::scope(|_| flood_in_pool(walls))
}

/// [`flood_outside`]'s rounds, run on a thread of the pool.
fn flood_in_pool(walls: &BrickSet) -> Flood {
    let mut bricks = PaddedBricks::new(walls);
    let mut wall_outside = vec![[0u64; 8]; walls.masks.len()];
    let pos: Vec<usize> = walls
        .keys
        .par_iter()
        .map(|&k| bricks.at(walls.index.coord(k as usize)))
        .collect();
    let (mut empty, mut active) = bricks.border_seeds(walls);
    loop {
        bricks.flood_empty(walls, &mut empty, &mut active);
        if active.is_empty() {
            break;
        }
        active.par_sort_unstable();
        active.dedup();
        let grown: Vec<(u32, BrickMask)> = active
            .par_iter()
            .with_min_len(ROUND_PIECE)
            .filter_map(|&s| {
                let out = pulled(walls, &bricks, &wall_outside, &pos, s as usize)?;
                Some((s, out))
            })
            .collect();
        for &(s, out) in &grown {
            wall_outside[s as usize] = out;
        }
        let reached: Vec<Reached> = grown
            .par_iter()
            .with_min_len(ROUND_PIECE)
            .flat_map_iter(|&(s, out)| {
                reached_from(walls, &bricks, &wall_outside, pos[s as usize], out)
            })
            .collect();
        active.clear();
        for r in reached {
            match r {
                Reached::Wall(t) => active.push(t),
                Reached::Empty(q) => bricks.mark_empty(q, &mut empty),
            }
        }
    }
    Flood {
        empty_outside: bricks.empty_outside(),
        wall_outside,
    }
}

/// Wall bricks a thread takes at least at once in a round: most rounds reach only a few, and
/// those are not worth splitting.
const ROUND_PIECE: usize = 64;

/// Wall brick `s`'s outside after pulling the faces its six neighbours carry into it and
/// growing within its walls, or `None` when that adds nothing (its outside is always grown
/// already).
fn pulled(
    walls: &BrickSet,
    bricks: &PaddedBricks,
    wall_outside: &[BrickMask],
    pos: &[usize],
    s: usize,
) -> Option<BrickMask> {
    let wall = &walls.masks[s];
    let old = wall_outside[s];
    let mut out = old;
    for (axis, high) in DIRS {
        let q = bricks.step(pos[s], axis, high);
        // What the neighbour on side (axis, high) carries across its face towards this brick.
        let carry = match bricks.state[q] {
            EMPTY => continue,
            WALL => {
                let t = walls.index.slots[bricks.key(q, walls)] as usize;
                face_carry(&wall_outside[t], axis, !high)
            }
            _ => face_carry(&FULL, axis, !high),
        };
        for z in 0..8 {
            out[z] |= carry[z] & !wall[z];
        }
    }
    if out == old {
        return None;
    }
    grow_within(&mut out, wall);
    Some(out)
}

/// A brick that a wall brick's grown outside reaches.
enum Reached {
    /// A wall brick (slot) that gains cells from it.
    Wall(u32),
    /// An empty brick (padded position) not yet known to be outside.
    Empty(usize),
}

/// The bricks that wall brick at padded position `p` with outside `out` carries new cells into.
fn reached_from<'a>(
    walls: &'a BrickSet,
    bricks: &'a PaddedBricks,
    wall_outside: &'a [BrickMask],
    p: usize,
    out: BrickMask,
) -> impl Iterator<Item = Reached> + 'a {
    DIRS.into_iter().filter_map(move |(axis, high)| {
        let q = bricks.step(p, axis, high);
        let state = bricks.state[q];
        if state != EMPTY && state != WALL {
            return None;
        }
        let carry = face_carry(&out, axis, high);
        if state == EMPTY {
            return (carry != [0; 8]).then_some(Reached::Empty(q));
        }
        let t = walls.index.slots[bricks.key(q, walls)];
        let (wall, known) = (&walls.masks[t as usize], &wall_outside[t as usize]);
        (0..8)
            .any(|z| carry[z] & !wall[z] & !known[z] != 0)
            .then_some(Reached::Wall(t))
    })
}

/// State of a brick in [`PaddedBricks`].
const EMPTY: u8 = 0;
/// An empty brick known to be outside.
const EMPTY_OUTSIDE: u8 = 1;
/// A brick with wall cells.
const WALL: u8 = 2;
/// The padding around the brick space.
const BEYOND: u8 = 3;

/// Brick states on the brick space padded by one brick each side, x fastest, so that the six
/// neighbours of any brick of the space are `p ± stride` without bounds checks.
struct PaddedBricks {
    dims: [usize; 3],
    stride: [usize; 3],
    state: Vec<u8>,
}

impl PaddedBricks {
    fn new(walls: &BrickSet) -> Self {
        let d = walls.index.dims.map(|v| v as usize);
        let dims = [d[0] + 2, d[1] + 2, d[2] + 2];
        let stride = [1, dims[0], dims[0] * dims[1]];
        let mut state = vec![BEYOND; dims[0] * dims[1] * dims[2]];
        state[stride[2]..(d[2] + 1) * stride[2]]
            .par_chunks_mut(stride[2])
            .enumerate()
            .for_each(|(z, plane)| {
                for y in 0..d[1] {
                    let row = (y + 1) * stride[1] + 1;
                    let key = (z * d[1] + y) * d[0];
                    for (st, &slot) in plane[row..row + d[0]]
                        .iter_mut()
                        .zip(&walls.index.slots[key..key + d[0]])
                    {
                        *st = if slot == NO_BRICK { EMPTY } else { WALL };
                    }
                }
            });
        Self {
            dims,
            stride,
            state,
        }
    }

    /// Padded position of brick `b`.
    #[inline]
    fn at(&self, b: [u32; 3]) -> usize {
        (b[0] as usize + 1)
            + (b[1] as usize + 1) * self.stride[1]
            + (b[2] as usize + 1) * self.stride[2]
    }

    /// The padded position next to `p` on side (`axis`, `high`).
    #[inline]
    fn step(&self, p: usize, axis: usize, high: bool) -> usize {
        if high {
            p + self.stride[axis]
        } else {
            p - self.stride[axis]
        }
    }

    /// Brick key (in the unpadded index) of padded position `p`.
    #[inline]
    fn key(&self, p: usize, walls: &BrickSet) -> usize {
        let x = p % self.dims[0] - 1;
        let y = (p / self.dims[0]) % self.dims[1] - 1;
        let z = p / self.stride[2] - 1;
        walls.index.key([x as u32, y as u32, z as u32])
    }

    /// The flood's seeds on the border of the brick space: its empty bricks, marked outside
    /// (padded positions), and its wall bricks (slots), which pull full faces from beyond.
    fn border_seeds(&mut self, walls: &BrickSet) -> (Vec<usize>, Vec<u32>) {
        let dims = walls.index.dims;
        let (mut empty, mut active) = (Vec::new(), Vec::new());
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                let inner = z > 0 && z + 1 < dims[2] && y > 0 && y + 1 < dims[1];
                let xs: &mut dyn Iterator<Item = u32> = if inner {
                    &mut [0, dims[0] - 1].into_iter()
                } else {
                    &mut (0..dims[0])
                };
                for x in xs {
                    let b = [x, y, z];
                    match walls.index.slots[walls.index.key(b)] {
                        NO_BRICK => self.mark_empty(self.at(b), &mut empty),
                        s => active.push(s),
                    }
                }
            }
        }
        (empty, active)
    }

    /// Marks the empty brick at padded position `p` outside, once, and stacks it.
    #[inline]
    fn mark_empty(&mut self, p: usize, stack: &mut Vec<usize>) {
        if self.state[p] == EMPTY {
            self.state[p] = EMPTY_OUTSIDE;
            stack.push(p);
        }
    }

    /// Floods the empty bricks from the outside ones on `stack` until it is empty; the wall
    /// bricks next to them (which pull full faces from them) go to `walls_reached` (slots).
    fn flood_empty(
        &mut self,
        walls: &BrickSet,
        stack: &mut Vec<usize>,
        walls_reached: &mut Vec<u32>,
    ) {
        while let Some(p) = stack.pop() {
            for (axis, high) in DIRS {
                let q = self.step(p, axis, high);
                match self.state[q] {
                    EMPTY => {
                        self.state[q] = EMPTY_OUTSIDE;
                        stack.push(q);
                    }
                    WALL => walls_reached.push(walls.index.slots[self.key(q, walls)]),
                    _ => {}
                }
            }
        }
    }

    /// Per brick key: whether it is an empty brick found outside.
    fn empty_outside(&self) -> Vec<bool> {
        let d = [self.dims[0] - 2, self.dims[1] - 2, self.dims[2] - 2];
        let mut out = vec![false; d[0] * d[1] * d[2]];
        out.par_chunks_mut(d[0] * d[1])
            .enumerate()
            .for_each(|(z, plane)| {
                for (y, row_out) in plane.chunks_mut(d[0]).enumerate() {
                    let row = (z + 1) * self.stride[2] + (y + 1) * self.stride[1] + 1;
                    for (o, &s) in row_out.iter_mut().zip(&self.state[row..row + d[0]]) {
                        *o = s == EMPTY_OUTSIDE;
                    }
                }
            });
        out
    }
}

/// What the flood says of one cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellSide {
    /// The surface touches the cell.
    Wall,
    /// Reached from the border without touching the surface.
    Outside,
    /// Not reached.
    Inside,
}

impl Flood {
    /// The outside cells of the brick with key `key` (`walls` indexes the bricks).
    #[inline]
    pub fn outside_cells(&self, walls: &BrickSet, key: usize) -> BrickMask {
        match walls.index.slots[key] {
            NO_BRICK if self.empty_outside[key] => FULL,
            NO_BRICK => [0; 8],
            s => self.wall_outside[s as usize],
        }
    }

    /// The inside cells (neither wall nor outside) of the brick with key `key`.
    #[inline]
    pub fn inside_cells(&self, walls: &BrickSet, key: usize) -> BrickMask {
        let outside = self.outside_cells(walls, key);
        let wall = match walls.index.slots[key] {
            NO_BRICK => [0; 8],
            s => walls.masks[s as usize],
        };
        std::array::from_fn(|z| !(outside[z] | wall[z]))
    }

    /// The side of cell `c`; cells outside the brick space are outside.
    #[inline]
    pub fn cell(&self, walls: &BrickSet, c: [i64; 3]) -> CellSide {
        if c.iter().any(|&v| v < 0) {
            return CellSide::Outside;
        }
        let (b, w, bit) = split([c[0] as u32, c[1] as u32, c[2] as u32]);
        let index = &walls.index;
        if (0..3).any(|a| b[a] >= index.dims[a]) {
            return CellSide::Outside;
        }
        let key = index.key(b);
        match index.slots[key] {
            NO_BRICK => {
                if self.empty_outside[key] {
                    CellSide::Outside
                } else {
                    CellSide::Inside
                }
            }
            s => {
                let s = s as usize;
                if test(&walls.masks[s], w, bit) {
                    CellSide::Wall
                } else if test(&self.wall_outside[s], w, bit) {
                    CellSide::Outside
                } else {
                    CellSide::Inside
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{pack, BrickIndex, BRICK};

    /// Walls at resolution 40: two hollow boxes (one with a gap in its shell) and scattered
    /// single cells, crossing brick borders.
    fn walls() -> BrickSet {
        let n = 40u32;
        let mut cells = Vec::new();
        for (lo, hi, gap) in [
            ([3u32, 4, 5], [20u32, 18, 22], false),
            ([22, 6, 9], [37, 30, 33], true),
        ] {
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let c = [x, y, z];
                        let on_shell = (0..3).any(|a| c[a] == lo[a] || c[a] == hi[a]);
                        let in_gap =
                            gap && x == lo[0] && (12..14).contains(&y) && (15..17).contains(&z);
                        if on_shell && !in_gap {
                            cells.push(c);
                        }
                    }
                }
            }
        }
        cells.extend((0..300u32).map(|i| [(i * 7919) % 39, (i * 104_729) % 39, (i * 31) % 39]));
        let index = BrickIndex::for_resolution(n);
        let mut packed: Vec<u64> = cells.iter().map(|&c| pack(&index, c)).collect();
        packed.sort_unstable();
        packed.dedup();
        BrickSet::from_sorted_packed(n, &packed)
    }

    #[test]
    fn flood_matches_a_cell_by_cell_search() {
        assert_matches_cell_by_cell_search(&walls());
    }

    #[test]
    fn flood_through_wall_bricks_matches_a_cell_by_cell_search() {
        // Dense random walls (a third of the cells, every brick a wall brick), so the outside
        // reaches most cells only through wall bricks, over many rounds; and walls two cells
        // apart with one-cell gaps in a winding order.
        let n = 48u32;
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut cells = Vec::new();
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    let maze = x % 3 == 1 && (y + 7 * (x / 3)) % 11 != 0;
                    if state.is_multiple_of(3) && z < n / 2 || maze && z >= n / 2 {
                        cells.push([x, y, z]);
                    }
                }
            }
        }
        let index = BrickIndex::for_resolution(n);
        let mut packed: Vec<u64> = cells.iter().map(|&c| pack(&index, c)).collect();
        packed.sort_unstable();
        packed.dedup();
        assert_matches_cell_by_cell_search(&BrickSet::from_sorted_packed(n, &packed));
    }

    /// Checks [`flood_outside`] cell by cell against a plain flood over cells.
    fn assert_matches_cell_by_cell_search(walls: &BrickSet) {
        let flood = flood_outside(walls);
        let side = (walls.index.dims[0] * BRICK) as i64;
        let at = |c: [i64; 3]| (c[0] + side * (c[1] + side * c[2])) as usize;
        let mut outside = vec![false; (side * side * side) as usize];
        let mut stack: Vec<[i64; 3]> = Vec::new();
        for z in 0..side {
            for y in 0..side {
                for x in 0..side {
                    let c = [x, y, z];
                    if c.iter().any(|&v| v == 0 || v == side - 1) && !walls.contains(c) {
                        outside[at(c)] = true;
                        stack.push(c);
                    }
                }
            }
        }
        while let Some(c) = stack.pop() {
            for k in 0..6 {
                let mut d = c;
                d[k / 2] += if k % 2 == 0 { -1 } else { 1 };
                if d.iter().all(|&v| (0..side).contains(&v))
                    && !outside[at(d)]
                    && !walls.contains(d)
                {
                    outside[at(d)] = true;
                    stack.push(d);
                }
            }
        }
        let mut counts = [0; 3];
        for z in 0..side {
            for y in 0..side {
                for x in 0..side {
                    let c = [x, y, z];
                    let want = if walls.contains(c) {
                        CellSide::Wall
                    } else if outside[at(c)] {
                        CellSide::Outside
                    } else {
                        CellSide::Inside
                    };
                    assert_eq!(flood.cell(walls, c), want, "cell {c:?}");
                    counts[want as usize] += 1;
                }
            }
        }
        assert!(
            counts.iter().all(|&k| k > 0),
            "walls, outside and inside all occur"
        );
    }
}
