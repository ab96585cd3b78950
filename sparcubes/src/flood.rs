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
pub fn flood_outside(walls: &BrickSet) -> Flood {
    let mut state = FloodState {
        walls,
        flood: Flood {
            empty_outside: vec![false; walls.index.slots.len()],
            wall_outside: vec![[0u64; 8]; walls.masks.len()],
        },
        queued: vec![false; walls.masks.len()],
        queue: VecDeque::new(),
    };
    state.seed_border();
    while let Some(key) = state.queue.pop_front() {
        let carries = state.outgoing_carries(key);
        let b = walls.index.coord(key);
        let dims = walls.index.dims;
        for (i, &(axis, high)) in DIRS.iter().enumerate() {
            if carries[i].iter().all(|&w| w == 0) {
                continue;
            }
            let mut nbr = [b[0] as i64, b[1] as i64, b[2] as i64];
            nbr[axis] += if high { 1 } else { -1 };
            if nbr[axis] < 0 || nbr[axis] >= dims[axis] as i64 {
                continue;
            }
            let nkey = walls
                .index
                .key([nbr[0] as u32, nbr[1] as u32, nbr[2] as u32]);
            state.carry_into(nkey, &carries[i]);
        }
    }
    state.flood
}

/// The flood in progress: its result so far and the queue of bricks to advance from.
struct FloodState<'a> {
    walls: &'a BrickSet,
    flood: Flood,
    /// Per wall brick: whether it is in the queue.
    queued: Vec<bool>,
    queue: VecDeque<usize>,
}

impl FloodState<'_> {
    /// Seeds every brick on the border of the brick space: an empty one is outside whole, a
    /// wall brick gets its non-wall cells on the border faces.
    fn seed_border(&mut self) {
        let index = &self.walls.index;
        let dims = index.dims;
        for key in 0..index.slots.len() {
            let b = index.coord(key);
            let mut border = DIRS
                .into_iter()
                .filter(|&(axis, high)| b[axis] == if high { dims[axis] - 1 } else { 0 })
                .peekable();
            if border.peek().is_none() {
                continue;
            }
            let slot = index.slots[key];
            if slot == NO_BRICK {
                self.flood.empty_outside[key] = true;
                self.queue.push_back(key);
                continue;
            }
            let s = slot as usize;
            let mut seed = [0u64; 8];
            for (axis, high) in border {
                // The face at local 0 (or 7) of this brick: carry a full face from the
                // opposite side onto it.
                or_assign(&mut seed, &face_carry(&FULL, axis, !high));
            }
            for z in 0..8 {
                seed[z] &= !self.walls.masks[s][z];
            }
            or_assign(&mut self.flood.wall_outside[s], &seed);
            self.queued[s] = true;
            self.queue.push_back(key);
        }
    }

    /// Grows brick `key`'s outside within its walls and returns what it carries across each
    /// of its six faces (in `DIRS` order); an empty outside brick carries full faces.
    fn outgoing_carries(&mut self, key: usize) -> [BrickMask; 6] {
        let slot = self.walls.index.slots[key];
        let mut c = [[0u64; 8]; 6];
        if slot == NO_BRICK {
            for (i, &(axis, high)) in DIRS.iter().enumerate() {
                c[i] = face_carry(&FULL, axis, high);
            }
            return c;
        }
        let s = slot as usize;
        self.queued[s] = false;
        let mut out = self.flood.wall_outside[s];
        grow_within(&mut out, &self.walls.masks[s]);
        self.flood.wall_outside[s] = out;
        for (i, &(axis, high)) in DIRS.iter().enumerate() {
            c[i] = face_carry(&out, axis, high);
        }
        c
    }

    /// Carries a face of outside cells into brick `nkey`, queueing it when that reaches
    /// cells (or, for an empty brick, the brick) not yet known to be outside.
    fn carry_into(&mut self, nkey: usize, carry: &BrickMask) {
        let nslot = self.walls.index.slots[nkey];
        if nslot == NO_BRICK {
            if !self.flood.empty_outside[nkey] {
                self.flood.empty_outside[nkey] = true;
                self.queue.push_back(nkey);
            }
            return;
        }
        let t = nslot as usize;
        let mut changed = false;
        for z in 0..8 {
            let incoming = carry[z] & !self.walls.masks[t][z] & !self.flood.wall_outside[t][z];
            if incoming != 0 {
                self.flood.wall_outside[t][z] |= incoming;
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
