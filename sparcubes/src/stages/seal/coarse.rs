//! A dense bit grid at the sealing scale ([`super::Scale`]): one bit per coarse cell, rows of
//! 64-bit words along x. At most 128³ cells at any resolution (256 KB of bits), so every
//! operation here is a pass over a few tens of thousands of words.

use crate::grid::{BrickIndex, BrickMask, BrickSet, BRICK};
use crate::stages::flood::Flood;

/// A set of coarse cells in the cube `0..side` per axis, as dense bits.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CoarseGrid {
    /// Cells per axis.
    pub side: usize,
    /// Words per row along x.
    words: usize,
    /// Rows (y fastest, then z), each `words` long; bits at x ≥ `side` are always clear.
    bits: Vec<u64>,
}

impl CoarseGrid {
    /// The empty set over `side³` cells.
    pub fn new(side: usize) -> Self {
        let words = side.div_ceil(64);
        Self {
            side,
            words,
            bits: vec![0; words * side * side],
        }
    }

    /// Position of the first word of row (y, z).
    #[inline]
    fn row(&self, y: usize, z: usize) -> usize {
        (z * self.side + y) * self.words
    }

    /// Whether cell `c` is in the set (`false` outside the cube).
    #[inline]
    pub fn get(&self, c: [i64; 3]) -> bool {
        if c.iter().any(|&v| v < 0 || v as usize >= self.side) {
            return false;
        }
        let (x, y, z) = (c[0] as usize, c[1] as usize, c[2] as usize);
        (self.bits[self.row(y, z) + x / 64] >> (x % 64)) & 1 == 1
    }

    /// Adds cell `c` (which must lie in the cube).
    #[inline]
    pub fn set(&mut self, c: [usize; 3]) {
        let i = self.row(c[1], c[2]) + c[0] / 64;
        self.bits[i] |= 1u64 << (c[0] % 64);
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.bits.iter().all(|&w| w == 0)
    }

    /// Number of cells in the set.
    #[cfg(test)]
    pub fn count(&self) -> u64 {
        self.bits.iter().map(|w| w.count_ones() as u64).sum()
    }

    /// `self ∧ other`.
    pub fn and(&self, other: &Self) -> Self {
        self.zip(other, |a, b| a & b)
    }

    /// `self ∧ ¬other`.
    pub fn and_not(&self, other: &Self) -> Self {
        self.zip(other, |a, b| a & !b)
    }

    /// `self ∨ other`.
    pub fn or(&self, other: &Self) -> Self {
        self.zip(other, |a, b| a | b)
    }

    /// The cells of the cube not in the set.
    pub fn complement(&self) -> Self {
        let mut out = self.clone();
        for w in out.bits.iter_mut() {
            *w = !*w;
        }
        out.clear_tail();
        out
    }

    fn zip(&self, other: &Self, f: impl Fn(u64, u64) -> u64) -> Self {
        let mut out = self.clone();
        for (o, &b) in out.bits.iter_mut().zip(&other.bits) {
            *o = f(*o, b);
        }
        out
    }

    /// Clears the bits at x ≥ `side` of every row.
    fn clear_tail(&mut self) {
        let used = self.side % 64;
        if used == 0 {
            return;
        }
        let keep = (1u64 << used) - 1;
        for r in 0..self.side * self.side {
            self.bits[r * self.words + self.words - 1] &= keep;
        }
    }

    /// Grows the set by `r` cells along every axis both ways (the cube of side `2r + 1`
    /// around each cell: Chebyshev distance ≤ r), separably and by doubling steps, so the
    /// cost is a few passes over the words whatever `r`.
    pub fn dilate(&self, r: usize) -> Self {
        let mut out = self.clone();
        for step in doubling_steps(r) {
            out.dilate_x(step);
        }
        for step in doubling_steps(r) {
            out.dilate_rows(step, 1);
        }
        for step in doubling_steps(r) {
            out.dilate_rows(step, self.side);
        }
        out
    }

    /// ORs every row with itself shifted by ±`k` cells along x (`k` < 64).
    fn dilate_x(&mut self, k: usize) {
        let w = self.words;
        let mut row = vec![0u64; w];
        for r in 0..self.side * self.side {
            let at = r * w;
            row.copy_from_slice(&self.bits[at..at + w]);
            for i in 0..w {
                let up = (row[i] << k) | if i > 0 { row[i - 1] >> (64 - k) } else { 0 };
                let down = (row[i] >> k) | if i + 1 < w { row[i + 1] << (64 - k) } else { 0 };
                self.bits[at + i] |= up | down;
            }
        }
        self.clear_tail();
    }

    /// ORs every row with the rows `±k` steps away, a step being `stride` rows (1: along y
    /// within a plane, `side`: along z).
    fn dilate_rows(&mut self, k: usize, stride: usize) {
        let before = self.bits.clone();
        let (w, s) = (self.words, self.side);
        for z in 0..s {
            for y in 0..s {
                let along = if stride == 1 { y } else { z };
                let at = self.row(y, z);
                for d in [k as i64, -(k as i64)] {
                    let o = along as i64 + d;
                    if o < 0 || o as usize >= s {
                        continue;
                    }
                    let from = (at as i64 + d * (stride * w) as i64) as usize;
                    for i in 0..w {
                        self.bits[at + i] |= before[from + i];
                    }
                }
            }
        }
    }

    /// The rows (y, z) that hold a cell of the set.
    pub fn rows_with_cells(&self) -> Vec<(usize, usize)> {
        let mut rows = Vec::new();
        for z in 0..self.side {
            for y in 0..self.side {
                if self.row_words(y, z).iter().any(|&w| w != 0) {
                    rows.push((y, z));
                }
            }
        }
        rows
    }

    /// The words of row (y, z).
    pub fn row_words(&self, y: usize, z: usize) -> &[u64] {
        let at = self.row(y, z);
        &self.bits[at..at + self.words]
    }

    /// ORs `words` into row (y, z).
    pub fn or_row(&mut self, y: usize, z: usize, words: &[u64]) {
        let at = self.row(y, z);
        for (b, w) in self.bits[at..at + self.words].iter_mut().zip(words) {
            *b |= w;
        }
    }

    /// Clears the cells of `words` in row (y, z).
    pub fn clear_row(&mut self, y: usize, z: usize, words: &[u64]) {
        let at = self.row(y, z);
        for (b, w) in self.bits[at..at + self.words].iter_mut().zip(words) {
            *b &= !w;
        }
    }

    /// Row (y, z) of the set grown by one face step (its own cells, their x neighbours, and
    /// the rows at y ± 1 and z ± 1), into `out`.
    pub fn grown_row(&self, y: usize, z: usize, out: &mut [u64]) {
        let w = self.words;
        let row = self.row_words(y, z);
        for i in 0..w {
            let up = (row[i] << 1) | if i > 0 { row[i - 1] >> 63 } else { 0 };
            let down = (row[i] >> 1) | if i + 1 < w { row[i + 1] << 63 } else { 0 };
            out[i] = row[i] | up | down;
        }
        let s = self.side;
        let near = [
            (y > 0).then(|| (y - 1, z)),
            (y + 1 < s).then_some((y + 1, z)),
            (z > 0).then(|| (y, z - 1)),
            (z + 1 < s).then_some((y, z + 1)),
        ];
        for (ny, nz) in near.into_iter().flatten() {
            for (o, b) in out.iter_mut().zip(self.row_words(ny, nz)) {
                *o |= b;
            }
        }
        if !s.is_multiple_of(64) {
            out[w - 1] &= (1u64 << (s % 64)) - 1;
        }
    }

    /// Row (y, z) of the cells on the faces of the cube (next to what lies beyond it).
    pub fn border_row(side: usize, y: usize, z: usize, out: &mut [u64]) {
        out.fill(0);
        if y == 0 || z == 0 || y + 1 == side || z + 1 == side {
            for x in 0..side {
                out[x / 64] |= 1u64 << (x % 64);
            }
        } else {
            out[0] |= 1;
            out[(side - 1) / 64] |= 1u64 << ((side - 1) % 64);
        }
    }

    /// The `k` bits (`k` ≤ 8, `x0` a multiple of `k`) of row (y, z) from x = `x0`, bit i for
    /// x0 + i; 0 outside the cube.
    pub fn row_bits(&self, x0: usize, y: usize, z: usize, k: usize) -> u64 {
        if y >= self.side || z >= self.side || x0 >= self.side {
            return 0;
        }
        let word = self.bits[self.row(y, z) + x0 / 64];
        (word >> (x0 % 64)) & ((1u64 << k) - 1)
    }

    /// Number of cells of row (y, z) in `x0..x1` (clipped to the cube; 0 outside it).
    pub fn count_in_row(&self, y: i64, z: i64, x0: i64, x1: i64) -> u64 {
        let s = self.side as i64;
        if y < 0 || z < 0 || y >= s || z >= s {
            return 0;
        }
        let (x0, x1) = (x0.max(0) as usize, x1.min(s) as usize);
        let row = self.row_words(y as usize, z as usize);
        let mut n = 0u64;
        let mut x = x0;
        while x < x1 {
            let (i, b) = (x / 64, x % 64);
            let take = (64 - b).min(x1 - x);
            let mask = if take == 64 {
                u64::MAX
            } else {
                ((1u64 << take) - 1) << b
            };
            n += (row[i] & mask).count_ones() as u64;
            x += take;
        }
        n
    }

    /// Number of pairs of face neighbours with one cell in `runs` and the other in the set.
    pub fn faces_with(&self, runs: &[Run]) -> u64 {
        let mut n = 0u64;
        for r in runs {
            let (y, z, x0, x1) = (r.y as i64, r.z as i64, r.x0 as i64, r.x1 as i64);
            n += self.count_in_row(y, z, x0 - 1, x0) + self.count_in_row(y, z, x1, x1 + 1);
            for (dy, dz) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
                n += self.count_in_row(y + dy, z + dz, x0, x1);
            }
        }
        n
    }

    /// Words per row.
    pub fn words(&self) -> usize {
        self.words
    }

    /// The set as runs of consecutive cells along x, in scan order (by z, then y, then x).
    pub fn runs(&self) -> Vec<Run> {
        let mut out = Vec::new();
        for z in 0..self.side {
            for y in 0..self.side {
                let at = self.row(y, z);
                let mut x = 0;
                while x < self.side {
                    let start = self.next_from(at, x, true);
                    if start >= self.side {
                        break;
                    }
                    let end = self.next_from(at, start, false).min(self.side);
                    out.push(Run {
                        y,
                        z,
                        x0: start,
                        x1: end,
                    });
                    x = end;
                }
            }
        }
        out
    }

    /// The first x ≥ `from` in the row at `at` whose bit is `set` (`side` rounded up to a
    /// word if there is none).
    fn next_from(&self, at: usize, from: usize, set: bool) -> usize {
        let mut i = from / 64;
        let mut word = self.bits[at + i] ^ if set { 0 } else { u64::MAX };
        word &= u64::MAX << (from % 64);
        loop {
            if word != 0 {
                return i * 64 + word.trailing_zeros() as usize;
            }
            i += 1;
            if i == self.words {
                return self.words * 64;
            }
            word = self.bits[at + i] ^ if set { 0 } else { u64::MAX };
        }
    }

    /// The cells of `runs`, as a set over `side³` cells.
    pub fn of_runs<'a>(side: usize, runs: impl IntoIterator<Item = &'a Run>) -> Self {
        let mut out = Self::new(side);
        runs.into_iter().for_each(|r| out.set_run(r));
        out
    }

    /// Adds the cells of a run.
    pub fn set_run(&mut self, run: &Run) {
        for x in run.x0..run.x1 {
            self.set([x, run.y, run.z]);
        }
    }

    /// Calls `f` with every cell of the set, x fastest, then y, then z.
    #[cfg(test)]
    pub fn for_each(&self, mut f: impl FnMut([usize; 3])) {
        for z in 0..self.side {
            for y in 0..self.side {
                let at = self.row(y, z);
                for i in 0..self.words {
                    let mut word = self.bits[at + i];
                    while word != 0 {
                        let b = word.trailing_zeros() as usize;
                        f([i * 64 + b, y, z]);
                        word &= word - 1;
                    }
                }
            }
        }
    }

    /// The set as bricks of a [`BrickSet`] over the coarse grid (resolution `side`), for the
    /// flood of [`crate::stages::flood`].
    pub fn to_bricks(&self) -> BrickSet {
        let index = BrickIndex::for_resolution(self.side as u32);
        let dims = index.dims;
        let mut keyed: Vec<(u32, BrickMask)> = Vec::new();
        for bz in 0..dims[2] as usize {
            for by in 0..dims[1] as usize {
                for bx in 0..dims[0] as usize {
                    let mut mask = [0u64; 8];
                    for lz in 0..8 {
                        for ly in 0..8 {
                            let byte = self.byte_at(bx * 8, by * 8 + ly, bz * 8 + lz);
                            mask[lz] |= (byte as u64) << (8 * ly);
                        }
                    }
                    if mask != [0; 8] {
                        let key = index.key([bx as u32, by as u32, bz as u32]) as u32;
                        keyed.push((key, mask));
                    }
                }
            }
        }
        BrickSet::from_masks(self.side as u32, keyed)
    }

    /// The 8 bits at x = `x0..x0 + 8` of row (y, z) (`x0` a multiple of 8); 0 beyond the cube.
    fn byte_at(&self, x0: usize, y: usize, z: usize) -> u8 {
        if y >= self.side || z >= self.side || x0 >= self.side {
            return 0;
        }
        let word = self.bits[self.row(y, z) + x0 / 64];
        (word >> (x0 % 64)) as u8
    }

    /// The cells a flood over the coarse grid (walls `walls`, from [`Self::to_bricks`])
    /// reached.
    pub fn from_flood(side: usize, walls: &BrickSet, flood: &Flood) -> Self {
        let mut out = Self::new(side);
        let index = &walls.index;
        for key in 0..index.slots.len() {
            let mask = flood.outside_cells(walls, key);
            if mask == [0; 8] {
                continue;
            }
            let b = index.coord(key);
            out.or_brick(b.map(|v| v as usize * BRICK as usize), &mask);
        }
        out
    }

    /// Adds the cells of a brick mask whose brick starts at coarse cell `origin`.
    fn or_brick(&mut self, origin: [usize; 3], mask: &BrickMask) {
        for lz in 0..8 {
            let z = origin[2] + lz;
            if z >= self.side || mask[lz] == 0 {
                continue;
            }
            for ly in 0..8 {
                let y = origin[1] + ly;
                let byte = (mask[lz] >> (8 * ly)) as u8;
                if y >= self.side || byte == 0 || origin[0] >= self.side {
                    continue;
                }
                let at = self.row(y, z) + origin[0] / 64;
                self.bits[at] |= (byte as u64) << (origin[0] % 64);
            }
        }
        self.clear_tail();
    }
}

/// Consecutive cells `x0..x1` of the row (y, z).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Run {
    /// Row.
    pub y: usize,
    /// Plane.
    pub z: usize,
    /// First cell.
    pub x0: usize,
    /// One past the last cell.
    pub x1: usize,
}

/// Steps whose doubling dilations add up to radius `r`: 1, 2, 4, … then the rest.
fn doubling_steps(r: usize) -> Vec<usize> {
    let mut steps = Vec::new();
    let mut radius = 0;
    while radius < r {
        let step = (radius + 1).min(r - radius);
        steps.push(step);
        radius += step;
    }
    steps
}

/// The coarse cells (of `cell` fine cells per axis, a power of two) that hold at least one
/// cell of the fine set `fine` (a [`BrickSet`] over the fine grid).
pub fn downsample(fine: &BrickSet, cell: u32, side: usize) -> CoarseGrid {
    let mut out = CoarseGrid::new(side);
    for (&key, mask) in fine.keys.iter().zip(&fine.masks) {
        if *mask == [0; 8] {
            continue;
        }
        let b = fine.index.coord(key as usize);
        let origin = b.map(|v| v as usize * BRICK as usize);
        if cell >= BRICK {
            out.set_clamped(origin.map(|v| v / cell as usize));
            continue;
        }
        for_each_block(cell as usize, |block, bits| {
            if (0..cell as usize).any(|dz| mask[block[2] * cell as usize + dz] & bits != 0) {
                let c: [usize; 3] = std::array::from_fn(|a| origin[a] / cell as usize + block[a]);
                out.set_clamped(c);
            }
        });
    }
    out
}

/// Calls `f(block, word bits)` for each block of `cell³` cells of a brick (`cell` = 1, 2 or
/// 4): its position in blocks, and the bits of a brick word (x + 8y) that its rows cover.
fn for_each_block(cell: usize, mut f: impl FnMut([usize; 3], u64)) {
    let per = BRICK as usize / cell;
    let row = (1u64 << cell) - 1;
    for bz in 0..per {
        for by in 0..per {
            // The block's rows of x = 0..cell, then moved along x below.
            let rows: u64 = (by * cell..(by + 1) * cell).fold(0, |b, y| b | row << (8 * y));
            for bx in 0..per {
                f([bx, by, bz], rows << (bx * cell));
            }
        }
    }
}

impl CoarseGrid {
    /// Adds cell `c` if it lies in the cube.
    fn set_clamped(&mut self, c: [usize; 3]) {
        if c.iter().all(|&v| v < self.side) {
            self.set(c);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute_dilate(g: &CoarseGrid, r: i64) -> CoarseGrid {
        let mut out = CoarseGrid::new(g.side);
        g.for_each(|c| {
            for dz in -r..=r {
                for dy in -r..=r {
                    for dx in -r..=r {
                        let p = [c[0] as i64 + dx, c[1] as i64 + dy, c[2] as i64 + dz];
                        if p.iter().all(|&v| v >= 0 && (v as usize) < g.side) {
                            out.set(p.map(|v| v as usize));
                        }
                    }
                }
            }
        });
        out
    }

    fn scattered(side: usize) -> CoarseGrid {
        let mut g = CoarseGrid::new(side);
        for i in 0..60usize {
            g.set([(i * 37) % side, (i * 101) % side, (i * 59) % side]);
        }
        g
    }

    #[test]
    fn dilation_matches_brute_force_across_words() {
        for side in [40, 70, 130] {
            let g = scattered(side);
            for r in [0, 1, 3, 4, 7] {
                assert_eq!(g.dilate(r), brute_dilate(&g, r as i64), "side {side} r {r}");
            }
        }
    }

    #[test]
    fn bricks_round_trip_through_the_flood_layout() {
        let g = scattered(70);
        let bricks = g.to_bricks();
        assert_eq!(bricks.len(), g.count());
        let mut back = CoarseGrid::new(70);
        for s in 0..bricks.keys.len() {
            bricks.for_each_member(s, |c| back.set(c.map(|v| v as usize)));
        }
        assert_eq!(back, g);
    }
}
