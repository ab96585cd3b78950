//! Stage 3: which cells are outside. A flood fill from the grid's border over cells the
//! surface does not touch, hierarchical as in OpenVDB's signed flood fill: whole empty bricks
//! are flooded at once, and inside bricks that hold wall cells the flood advances with
//! bit-parallel dilations of 512-bit masks. Cells it never reaches are inside.

use crate::grid::{face_carry, or_assign, shift, split, test, BrickMask, BrickSet, NO_BRICK};
use std::collections::VecDeque;

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
const DIRS: [(usize, bool); 6] = [
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
/// brick space. The result is the unique least fixpoint, so it does not depend on order.
///
/// Two work lists: empty bricks (most of the grid) are expanded with a stack over a padded
/// byte grid of brick states (no bounds checks, no face masks, 1 byte a brick); wall bricks go
/// through a queue that grows their outside cells and carries faces. Whichever list is
/// drained first, the fixpoint is the same.
pub fn flood_outside(walls: &BrickSet) -> Flood {
    let mut state = FloodState {
        walls,
        bricks: PaddedBricks::new(walls),
        wall_outside: vec![[0u64; 8]; walls.masks.len()],
        queued: vec![false; walls.masks.len()],
        queue: VecDeque::new(),
        empty: Vec::new(),
    };
    state.seed_border();
    loop {
        if let Some(p) = state.empty.pop() {
            state.expand_empty(p);
        } else if let Some(key) = state.queue.pop_front() {
            state.expand_wall(key);
        } else {
            break;
        }
    }
    Flood {
        empty_outside: state.bricks.empty_outside(),
        wall_outside: state.wall_outside,
    }
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
        for z in 0..d[2] {
            for y in 0..d[1] {
                let row = (z + 1) * stride[2] + (y + 1) * stride[1] + 1;
                let key = (z * d[1] + y) * d[0];
                for (st, &slot) in state[row..row + d[0]]
                    .iter_mut()
                    .zip(&walls.index.slots[key..key + d[0]])
                {
                    *st = if slot == NO_BRICK { EMPTY } else { WALL };
                }
            }
        }
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

    /// Brick key (in the unpadded index) of padded position `p`.
    #[inline]
    fn key(&self, p: usize, walls: &BrickSet) -> usize {
        let x = p % self.dims[0] - 1;
        let y = (p / self.dims[0]) % self.dims[1] - 1;
        let z = p / self.stride[2] - 1;
        walls.index.key([x as u32, y as u32, z as u32])
    }

    /// Per brick key: whether it is an empty brick found outside.
    fn empty_outside(&self) -> Vec<bool> {
        let d = [self.dims[0] - 2, self.dims[1] - 2, self.dims[2] - 2];
        let mut out = Vec::with_capacity(d[0] * d[1] * d[2]);
        for z in 0..d[2] {
            for y in 0..d[1] {
                let row = (z + 1) * self.stride[2] + (y + 1) * self.stride[1] + 1;
                out.extend(
                    self.state[row..row + d[0]]
                        .iter()
                        .map(|&s| s == EMPTY_OUTSIDE),
                );
            }
        }
        out
    }
}

/// The flood in progress: its result so far and the bricks to advance from.
struct FloodState<'a> {
    walls: &'a BrickSet,
    bricks: PaddedBricks,
    /// Per wall brick (parallel to `walls.masks`): its outside cells so far.
    wall_outside: Vec<BrickMask>,
    /// Per wall brick: whether it is in the queue.
    queued: Vec<bool>,
    /// Wall bricks (keys) whose outside grew since they last carried.
    queue: VecDeque<usize>,
    /// Empty bricks (padded positions) found outside that have not carried yet.
    empty: Vec<usize>,
}

impl FloodState<'_> {
    /// Seeds every brick on the border of the brick space: an empty one is outside whole, a
    /// wall brick gets its non-wall cells on the border faces.
    fn seed_border(&mut self) {
        let dims = self.walls.index.dims;
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                let inner = z > 0 && z + 1 < dims[2] && y > 0 && y + 1 < dims[1];
                let xs: &mut dyn Iterator<Item = u32> = if inner {
                    &mut [0, dims[0] - 1].into_iter()
                } else {
                    &mut (0..dims[0])
                };
                for x in xs {
                    self.seed_brick([x, y, z]);
                }
            }
        }
    }

    /// Seeds brick `b`, which lies on the border of the brick space.
    fn seed_brick(&mut self, b: [u32; 3]) {
        let index = &self.walls.index;
        let dims = index.dims;
        let key = index.key(b);
        let slot = index.slots[key];
        if slot == NO_BRICK {
            self.mark_empty(self.bricks.at(b));
            return;
        }
        let s = slot as usize;
        let mut seed = [0u64; 8];
        for (axis, high) in DIRS {
            if b[axis] == if high { dims[axis] - 1 } else { 0 } {
                // The face at local 0 (or 7) of this brick: carry a full face from the
                // opposite side onto it.
                or_assign(&mut seed, &face_carry(&FULL, axis, !high));
            }
        }
        for z in 0..8 {
            seed[z] &= !self.walls.masks[s][z];
        }
        or_assign(&mut self.wall_outside[s], &seed);
        if !self.queued[s] {
            self.queued[s] = true;
            self.queue.push_back(key);
        }
    }

    /// Marks the empty brick at padded position `p` outside, once.
    #[inline]
    fn mark_empty(&mut self, p: usize) {
        if self.bricks.state[p] == EMPTY {
            self.bricks.state[p] = EMPTY_OUTSIDE;
            self.empty.push(p);
        }
    }

    /// An empty outside brick: marks its empty neighbours outside and carries a full face
    /// into its wall neighbours.
    fn expand_empty(&mut self, p: usize) {
        for (axis, high) in DIRS {
            let q = if high {
                p + self.bricks.stride[axis]
            } else {
                p - self.bricks.stride[axis]
            };
            match self.bricks.state[q] {
                EMPTY => {
                    self.bricks.state[q] = EMPTY_OUTSIDE;
                    self.empty.push(q);
                }
                WALL => {
                    let key = self.bricks.key(q, self.walls);
                    self.carry_into(key, &face_carry(&FULL, axis, high));
                }
                _ => {}
            }
        }
    }

    /// A wall brick whose outside grew: grows it within its walls and carries its faces.
    fn expand_wall(&mut self, key: usize) {
        let carries = self.outgoing_carries(key);
        let b = self.walls.index.coord(key);
        let dims = self.walls.index.dims;
        for (i, &(axis, high)) in DIRS.iter().enumerate() {
            if carries[i].iter().all(|&w| w == 0) {
                continue;
            }
            let mut nbr = [b[0] as i64, b[1] as i64, b[2] as i64];
            nbr[axis] += if high { 1 } else { -1 };
            if nbr[axis] < 0 || nbr[axis] >= dims[axis] as i64 {
                continue;
            }
            let nbr = [nbr[0] as u32, nbr[1] as u32, nbr[2] as u32];
            let nkey = self.walls.index.key(nbr);
            if self.walls.index.slots[nkey] == NO_BRICK {
                self.mark_empty(self.bricks.at(nbr));
            } else {
                self.carry_into(nkey, &carries[i]);
            }
        }
    }

    /// Grows wall brick `key`'s outside within its walls and returns what it carries across
    /// each of its six faces (in `DIRS` order).
    fn outgoing_carries(&mut self, key: usize) -> [BrickMask; 6] {
        let s = self.walls.index.slots[key] as usize;
        let mut c = [[0u64; 8]; 6];
        self.queued[s] = false;
        let mut out = self.wall_outside[s];
        grow_within(&mut out, &self.walls.masks[s]);
        self.wall_outside[s] = out;
        for (i, &(axis, high)) in DIRS.iter().enumerate() {
            c[i] = face_carry(&out, axis, high);
        }
        c
    }

    /// Carries a face of outside cells into wall brick `nkey`, queueing it when that reaches
    /// cells not yet known to be outside.
    fn carry_into(&mut self, nkey: usize, carry: &BrickMask) {
        let t = self.walls.index.slots[nkey] as usize;
        let mut changed = false;
        for z in 0..8 {
            let incoming = carry[z] & !self.walls.masks[t][z] & !self.wall_outside[t][z];
            if incoming != 0 {
                self.wall_outside[t][z] |= incoming;
                changed = true;
            }
        }
        if changed && !self.queued[t] {
            self.queued[t] = true;
            self.queue.push_back(nkey);
        }
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
        let walls = walls();
        let flood = flood_outside(&walls);
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
                    assert_eq!(flood.cell(&walls, c), want, "cell {c:?}");
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
