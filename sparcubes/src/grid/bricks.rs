//! The sparse grid's data structures: bricks of 8³ cells (or vertices) with a 512-bit mask,
//! addressed through a dense index over brick coordinates (4 bytes per brick, so about 9 MB
//! at N = 1024 — never a dense array per cell).
//!
//! Cells and vertices share one brick space: brick `b` holds cells / vertices whose integer
//! coordinates `c` satisfy `c >> 3 == b`. A brick mask is eight `u64` words, word `z & 7`,
//! bit `(x & 7) + 8 · (y & 7)`.

/// Edge length of a brick, in cells.
pub const BRICK: u32 = 8;
/// Sentinel in a brick index for "no brick here".
pub const NO_BRICK: u32 = u32::MAX;

/// One brick's bits: word = local z, bit = local x + 8 · local y.
pub type BrickMask = [u64; 8];

/// Bits of a brick word whose local x is 0.
pub const X0: u64 = 0x0101_0101_0101_0101;
/// Bits of a brick word whose local x is 7.
pub const X7: u64 = X0 << 7;
/// Bits of a brick word whose local y is 0.
pub const Y0: u64 = 0xFF;
/// Bits of a brick word whose local y is 7.
pub const Y7: u64 = 0xFF << 56;

/// Splits a cell or vertex coordinate into (brick coordinate, word, bit).
#[inline]
pub fn split(c: [u32; 3]) -> ([u32; 3], usize, u32) {
    (
        [c[0] >> 3, c[1] >> 3, c[2] >> 3],
        (c[2] & 7) as usize,
        (c[0] & 7) + 8 * (c[1] & 7),
    )
}

/// Whether bit `(word, bit)` is set.
#[inline]
pub fn test(m: &BrickMask, word: usize, bit: u32) -> bool {
    (m[word] >> bit) & 1 == 1
}

/// Number of set bits.
#[inline]
pub fn count(m: &BrickMask) -> u32 {
    m.iter().map(|w| w.count_ones()).sum()
}

/// Number of set bits before `(word, bit)` in local order.
#[inline]
pub fn rank(m: &BrickMask, word: usize, bit: u32) -> u32 {
    let before: u32 = m[..word].iter().map(|w| w.count_ones()).sum();
    before + (m[word] & ((1u64 << bit) - 1)).count_ones()
}

/// Whether the mask is empty.
#[inline]
pub fn is_empty(m: &BrickMask) -> bool {
    m.iter().all(|&w| w == 0)
}

/// The offsets of the cube `-r..=r` per axis around a point, x fastest, then y, then z
/// (`r = 1`: the point and its 26 neighbours).
pub fn cube_offsets(r: i64) -> impl Iterator<Item = [i64; 3]> {
    let w = 2 * r + 1;
    (0..w * w * w).map(move |d| [d % w - r, (d / w) % w - r, d / (w * w) - r])
}

/// Calls `f(local x, local y, local z)` for each set bit, in local order.
#[inline]
pub fn for_each_bit(m: &BrickMask, mut f: impl FnMut(u32, u32, u32)) {
    for (z, &word) in m.iter().enumerate() {
        let mut w = word;
        while w != 0 {
            let b = w.trailing_zeros();
            f(b & 7, b >> 3, z as u32);
            w &= w - 1;
        }
    }
}

/// The dense index of a brick space: brick coordinate → slot in a sparse list.
#[derive(Debug, Clone)]
pub struct BrickIndex {
    /// Bricks per axis.
    pub dims: [u32; 3],
    /// Slot per brick (x fastest), or [`NO_BRICK`].
    pub slots: Vec<u32>,
}

impl BrickIndex {
    /// An empty index over a brick space covering coordinates `0..=n` per axis.
    pub fn for_resolution(n: u32) -> Self {
        let d = n / BRICK + 1;
        Self {
            dims: [d; 3],
            slots: vec![NO_BRICK; (d as usize).pow(3)],
        }
    }

    /// The index of a brick space covering `0..=n` per axis whose bricks `keys` (ascending,
    /// distinct) hold slots `0..keys.len()`. Filled in parallel over fixed ranges of keys,
    /// each range setting its own bricks: at N = 1024 the index is 8.6 MB, and filling it on
    /// one thread showed up in every stage that builds a set.
    pub fn with_keys(n: u32, keys: &[u32]) -> Self {
        use rayon::prelude::*;
        const RANGE: usize = 1 << 16;
        let d = n / BRICK + 1;
        let len = (d as usize).pow(3);
        let mut slots: Vec<u32> = (0..len)
            .into_par_iter()
            .with_min_len(RANGE)
            .map(|_| NO_BRICK)
            .collect();
        slots
            .par_chunks_mut(RANGE)
            .enumerate()
            .for_each(|(c, range)| {
                let lo = c * RANGE;
                let first = keys.partition_point(|&k| (k as usize) < lo);
                for (i, &k) in keys[first..].iter().enumerate() {
                    let Some(slot) = range.get_mut(k as usize - lo) else {
                        break;
                    };
                    *slot = (first + i) as u32;
                }
            });
        Self {
            dims: [d; 3],
            slots,
        }
    }

    /// Linear key of a brick coordinate (x fastest).
    #[inline]
    pub fn key(&self, b: [u32; 3]) -> usize {
        (b[0] + self.dims[0] * (b[1] + self.dims[1] * b[2])) as usize
    }

    /// Brick coordinate of a linear key.
    #[inline]
    pub fn coord(&self, key: usize) -> [u32; 3] {
        let k = key as u32;
        [
            k % self.dims[0],
            (k / self.dims[0]) % self.dims[1],
            k / (self.dims[0] * self.dims[1]),
        ]
    }

    /// Slot of brick `b`, if present; `None` also for coordinates outside the space.
    #[inline]
    pub fn slot(&self, b: [i64; 3]) -> Option<usize> {
        if (0..3).any(|a| b[a] < 0 || b[a] >= self.dims[a] as i64) {
            return None;
        }
        let s = self.slots[self.key([b[0] as u32, b[1] as u32, b[2] as u32])];
        (s != NO_BRICK).then_some(s as usize)
    }
}

/// A sparse set of cells or vertices: bricks with their masks, sorted by linear key.
#[derive(Debug, Clone)]
pub struct BrickSet {
    /// Dense index from brick coordinate to position in `keys`/`masks`.
    pub index: BrickIndex,
    /// Linear keys of the present bricks, ascending.
    pub keys: Vec<u32>,
    /// Mask per present brick (parallel to `keys`).
    pub masks: Vec<BrickMask>,
}

impl BrickSet {
    /// Calls `f` with the grid coordinates of each member of the brick in slot `s`, in local
    /// order.
    #[inline]
    pub fn for_each_member(&self, s: usize, mut f: impl FnMut([i64; 3])) {
        let b = self.index.coord(self.keys[s] as usize);
        for_each_bit(&self.masks[s], |x, y, z| {
            f([
                (b[0] * 8 + x) as i64,
                (b[1] * 8 + y) as i64,
                (b[2] * 8 + z) as i64,
            ])
        });
    }

    /// Builds a set from sorted, deduplicated `(brick key, word, bit)`-packed entries
    /// (`key << 9 | local`), where `local = x + 8y + 64z`.
    pub fn from_sorted_packed(n: u32, packed: &[u64]) -> Self {
        let mut index = BrickIndex::for_resolution(n);
        let mut keys = Vec::new();
        let mut masks: Vec<BrickMask> = Vec::new();
        for &p in packed {
            let key = (p >> 9) as u32;
            let local = (p & 511) as u32;
            if keys.last() != Some(&key) {
                index.slots[key as usize] = keys.len() as u32;
                keys.push(key);
                masks.push([0; 8]);
            }
            if let Some(m) = masks.last_mut() {
                m[(local >> 6) as usize] |= 1u64 << (local & 63);
            }
        }
        Self { index, keys, masks }
    }

    /// Builds a set from bricks given as sorted keys with their masks (empty masks dropped).
    pub fn from_masks(index_dims_n: u32, keyed: Vec<(u32, BrickMask)>) -> Self {
        let mut keys = Vec::with_capacity(keyed.len());
        let mut masks = Vec::with_capacity(keyed.len());
        for (k, m) in keyed {
            if is_empty(&m) {
                continue;
            }
            keys.push(k);
            masks.push(m);
        }
        let index = BrickIndex::with_keys(index_dims_n, &keys);
        Self { index, keys, masks }
    }

    /// Whether the cell / vertex at `c` is in the set (`false` outside the space).
    #[inline]
    pub fn contains(&self, c: [i64; 3]) -> bool {
        if c.iter().any(|&v| v < 0) {
            return false;
        }
        let (b, w, bit) = split([c[0] as u32, c[1] as u32, c[2] as u32]);
        match self.index.slot([b[0] as i64, b[1] as i64, b[2] as i64]) {
            Some(s) => test(&self.masks[s], w, bit),
            None => false,
        }
    }

    /// Mask of the brick at brick coordinate `b`, if present.
    #[inline]
    pub fn mask_at(&self, b: [i64; 3]) -> Option<&BrickMask> {
        self.index.slot(b).map(|s| &self.masks[s])
    }

    /// Total number of members.
    pub fn len(&self) -> u64 {
        self.masks.iter().map(|m| count(m) as u64).sum()
    }

    /// Whether the set has no member.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }
}

/// Packs a cell / vertex coordinate as `brick key << 9 | local index` for sorting.
#[inline]
pub fn pack(index: &BrickIndex, c: [u32; 3]) -> u64 {
    let (b, w, bit) = split(c);
    ((index.key(b) as u64) << 9) | ((w as u64) << 6) | bit as u64
}

/// Shifts of a mask by one along an axis within a brick, with the bits that leave the brick
/// dropped: `plus` moves every bit from local coordinate k to k + 1.
#[inline]
pub fn shift(m: &BrickMask, axis: usize, plus: bool) -> BrickMask {
    let mut out = [0u64; 8];
    match (axis, plus) {
        (0, true) => (0..8).for_each(|z| out[z] = (m[z] << 1) & !X0),
        (0, false) => (0..8).for_each(|z| out[z] = (m[z] >> 1) & !X7),
        (1, true) => (0..8).for_each(|z| out[z] = m[z] << 8),
        (1, false) => (0..8).for_each(|z| out[z] = m[z] >> 8),
        (2, true) => (1..8).for_each(|z| out[z] = m[z - 1]),
        _ => (0..7).for_each(|z| out[z] = m[z + 1]),
    }
    out
}

/// The bits of `m` on its face at local coordinate 7 (`high`) or 0 along `axis`, moved to the
/// opposite face (as they enter the neighbouring brick).
#[inline]
pub fn face_carry(m: &BrickMask, axis: usize, high: bool) -> BrickMask {
    let mut out = [0u64; 8];
    match (axis, high) {
        (0, true) => (0..8).for_each(|z| out[z] = (m[z] & X7) >> 7),
        (0, false) => (0..8).for_each(|z| out[z] = (m[z] & X0) << 7),
        (1, true) => (0..8).for_each(|z| out[z] = (m[z] & Y7) >> 56),
        (1, false) => (0..8).for_each(|z| out[z] = (m[z] & Y0) << 56),
        (2, true) => out[0] = m[7],
        _ => out[7] = m[0],
    }
    out
}

/// The members of `a` that are not in `b`, in `a`'s bricks (emptied bricks are dropped).
pub fn difference(a: &BrickSet, b: &BrickSet, n: u32) -> BrickSet {
    let keyed = a
        .keys
        .iter()
        .zip(&a.masks)
        .map(|(&k, m)| match b.index.slots[k as usize] {
            NO_BRICK => (k, *m),
            s => {
                let other = &b.masks[s as usize];
                (k, std::array::from_fn(|z| m[z] & !other[z]))
            }
        })
        .collect();
    BrickSet::from_masks(n, keyed)
}

/// Merges two key-sorted lists of brick masks, OR-ing the masks of a key in both.
pub fn merge_masks(a: Vec<(u32, BrickMask)>, b: Vec<(u32, BrickMask)>) -> Vec<(u32, BrickMask)> {
    let mut out = Vec::with_capacity(a.len() + b.len());
    let mut b = b.into_iter().peekable();
    for (key, mut mask) in a {
        while let Some(&(k, m)) = b.peek() {
            if k > key {
                break;
            }
            if k == key {
                or_assign(&mut mask, &m);
            } else {
                out.push((k, m));
            }
            b.next();
        }
        out.push((key, mask));
    }
    out.extend(b);
    out
}

/// Bitwise OR in place.
#[inline]
pub fn or_assign(a: &mut BrickMask, b: &BrickMask) {
    for z in 0..8 {
        a[z] |= b[z];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nth_bit_walks_words() {
        let mut m = [0u64; 8];
        m[0] = 0b1010;
        m[2] = 1 << 7;
        assert_eq!(nth_bit(&m, 0), 1);
        assert_eq!(nth_bit(&m, 1), 3);
        assert_eq!(nth_bit(&m, 2), 128 + 7);
    }

    #[test]
    fn cube_offsets_cover_the_cube_once_x_fastest() {
        let one: Vec<[i64; 3]> = cube_offsets(1).collect();
        assert_eq!(one.len(), 27);
        assert_eq!(one[0], [-1, -1, -1]);
        assert_eq!(one[1], [0, -1, -1]);
        assert_eq!(one[3], [-1, 0, -1]);
        assert_eq!(one[13], [0, 0, 0]);
        assert_eq!(one[26], [1, 1, 1]);
        let four: std::collections::BTreeSet<[i64; 3]> = cube_offsets(4).collect();
        assert_eq!(four.len(), 729);
        assert!(four.iter().all(|o| o.iter().all(|v| v.abs() <= 4)));
    }

    #[test]
    fn rank_counts_bits_before() {
        let mut m = [0u64; 8];
        m[0] = 0b1011;
        m[3] = 1 << 5;
        assert_eq!(rank(&m, 0, 0), 0);
        assert_eq!(rank(&m, 0, 3), 2);
        assert_eq!(rank(&m, 3, 5), 3);
        assert_eq!(rank(&m, 3, 6), 4);
        assert_eq!(count(&m), 4);
    }

    /// A scattered set of cells or vertices within `0..40` per axis, crossing brick borders.
    fn scattered() -> (Vec<[u32; 3]>, BrickSet) {
        let mut coords: Vec<[u32; 3]> = (0..400u32)
            .map(|i| {
                [
                    (i * 7919) % 37 + 1,
                    (i * 104_729) % 33 + 2,
                    (i * 1_299_709) % 35 + 1,
                ]
            })
            .collect();
        coords.sort_unstable();
        coords.dedup();
        let index = BrickIndex::for_resolution(40);
        let mut packed: Vec<u64> = coords.iter().map(|&c| pack(&index, c)).collect();
        packed.sort_unstable();
        (coords, BrickSet::from_sorted_packed(40, &packed))
    }

    #[test]
    fn coords_of_answers_numbers_in_any_order() {
        // The inside test asks for the corners of a part in the order it meets them, not in
        // number order: a number below the previous one went back no brick, subtracted past
        // zero (a panic with overflow checks, brick coordinates of the wrong brick without).
        let (_, set) = scattered();
        let numbered = Numbered::new(set);
        let all = numbered.coords();
        let ids: Vec<u32> = (0..numbered.len as u32).rev().step_by(3).collect();
        let expected: Vec<[u32; 3]> = ids.iter().map(|&i| all[i as usize]).collect();
        assert!(numbered.offsets.iter().filter(|&&o| o > 0).count() > 2);
        assert_eq!(numbered.coords_of(&ids), expected);
        let shuffled: Vec<u32> = ids
            .iter()
            .map(|&i| (i * 37) % numbered.len as u32)
            .collect();
        let expected: Vec<[u32; 3]> = shuffled.iter().map(|&i| all[i as usize]).collect();
        assert_eq!(numbered.coords_of(&shuffled), expected);
    }

    #[test]
    fn sorted_members_lists_every_member_in_order() {
        let (coords, set) = scattered();
        let got: Vec<[u32; 3]> = set
            .sorted_members()
            .iter()
            .map(|c| c.map(|v| v as u32))
            .collect();
        assert_eq!(got, coords);
    }

    #[test]
    fn dilations_match_brute_force() {
        let (coords, set) = scattered();
        for (how, offsets) in [(Dilation::Corners, [0i64, 1]), (Dilation::Cells, [-1, 0])] {
            let mut want = Vec::new();
            for c in &coords {
                for d in 0..8 {
                    let o = [offsets[d & 1], offsets[(d >> 1) & 1], offsets[d >> 2]];
                    let v: [i64; 3] = std::array::from_fn(|a| c[a] as i64 + o[a]);
                    if v.iter().all(|&x| x >= 0) {
                        want.push(v.map(|x| x as u16));
                    }
                }
            }
            want.sort_unstable();
            want.dedup();
            assert_eq!(dilate(&set, 40, how).sorted_members(), want, "{how:?}");
        }
        let grown = dilate(&set, 40, Dilation::Corners);
        let rest = difference(&grown, &set, 40);
        assert_eq!(rest.len(), grown.len() - set.len());
        assert!(coords.iter().all(|&c| !rest.contains(c.map(|v| v as i64))));
    }

    #[test]
    fn shift_and_carry_move_bits_across_axes() {
        let mut m = [0u64; 8];
        let (_, w, b) = split([7, 3, 2]);
        m[w] |= 1 << b;
        let s = shift(&m, 0, true);
        assert!(is_empty(&s), "a bit at x = 7 leaves the brick");
        let c = face_carry(&m, 0, true);
        let (_, w2, b2) = split([0, 3, 2]);
        assert!(test(&c, w2, b2));
        let s = shift(&m, 2, false);
        let (_, w3, b3) = split([7, 3, 1]);
        assert!(test(&s, w3, b3));
    }
}

/// How [`dilate`] grows a set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dilation {
    /// By one along every axis both ways: the 26-neighbourhood.
    Box,
    /// By one towards +x, +y and +z: the corners of a set of cells.
    Corners,
    /// By one towards −x, −y and −z: the cells a set of vertices are corners of.
    Cells,
}

/// Grows a set by one (see [`Dilation`]), separably per axis; coordinates that would fall
/// outside the brick space are dropped.
pub fn dilate(set: &BrickSet, n: u32, how: Dilation) -> BrickSet {
    use rayon::prelude::*;
    let index = &set.index;
    let dims = index.dims;
    let reach: &[i64] = match how {
        Dilation::Box => &[-1, 0, 1],
        Dilation::Corners => &[0, 1],
        Dilation::Cells => &[-1, 0],
    };
    let mut keys: Vec<u32> = set
        .keys
        .par_iter()
        .with_min_len(1024)
        .fold(Vec::new, |mut near, &k| {
            let b = index.coord(k as usize);
            for &dz in reach {
                for &dy in reach {
                    for &dx in reach {
                        let c = [b[0] as i64 + dx, b[1] as i64 + dy, b[2] as i64 + dz];
                        if (0..3).all(|a| c[a] >= 0 && c[a] < dims[a] as i64) {
                            near.push(index.key([c[0] as u32, c[1] as u32, c[2] as u32]) as u32);
                        }
                    }
                }
            }
            near
        })
        .reduce(Vec::new, |mut a, b| {
            a.extend(b);
            a
        });
    // Sorted, so the order the parts were gathered in does not matter.
    keys.par_sort_unstable();
    keys.dedup();
    let grown = BrickIndex::with_keys(n, &keys);
    let mut masks: Vec<BrickMask> = keys
        .par_iter()
        .map(|&k| match set.index.slots[k as usize] {
            NO_BRICK => [0; 8],
            s => set.masks[s as usize],
        })
        .collect();
    let (plus, minus) = (how != Dilation::Cells, how != Dilation::Corners);
    for axis in 0..3 {
        let before = &masks;
        masks = (0..keys.len())
            .into_par_iter()
            .map(|i| {
                let b = grown.coord(keys[i] as usize);
                let m = &before[i];
                let mut out = *m;
                let mut lower = [b[0] as i64, b[1] as i64, b[2] as i64];
                lower[axis] -= 1;
                let mut upper = [b[0] as i64, b[1] as i64, b[2] as i64];
                upper[axis] += 1;
                if plus {
                    or_assign(&mut out, &shift(m, axis, true));
                    if let Some(s) = grown.slot(lower) {
                        or_assign(&mut out, &face_carry(&before[s], axis, true));
                    }
                }
                if minus {
                    or_assign(&mut out, &shift(m, axis, false));
                    if let Some(s) = grown.slot(upper) {
                        or_assign(&mut out, &face_carry(&before[s], axis, false));
                    }
                }
                out
            })
            .collect();
    }
    BrickSet {
        index: grown,
        keys,
        masks,
    }
}

/// A [`BrickSet`] whose members are numbered `0..len` in brick order, so per-member data can
/// live in flat arrays.
#[derive(Debug, Clone)]
pub struct Numbered {
    /// The members.
    pub set: BrickSet,
    /// Per brick: the number of the brick's first member.
    pub offsets: Vec<u32>,
    /// Total members.
    pub len: usize,
}

impl Numbered {
    /// Numbers the members of `set`.
    pub fn new(set: BrickSet) -> Self {
        let mut offsets = Vec::with_capacity(set.masks.len());
        let mut total = 0u64;
        for m in &set.masks {
            offsets.push(total as u32);
            total += count(m) as u64;
        }
        Self {
            set,
            offsets,
            len: total as usize,
        }
    }

    /// Number of the member at `c`, if it is one.
    #[inline]
    pub fn id(&self, c: [i64; 3]) -> Option<u32> {
        if c.iter().any(|&v| v < 0) {
            return None;
        }
        let (b, w, bit) = split([c[0] as u32, c[1] as u32, c[2] as u32]);
        let s = self
            .set
            .index
            .slot([b[0] as i64, b[1] as i64, b[2] as i64])?;
        let m = &self.set.masks[s];
        test(m, w, bit).then(|| self.offsets[s] + rank(m, w, bit))
    }

    /// Coordinates of every member, in number order.
    pub fn coords(&self) -> Vec<[u32; 3]> {
        let mut out = Vec::with_capacity(self.len);
        for (s, m) in self.set.masks.iter().enumerate() {
            let b = self.set.index.coord(self.set.keys[s] as usize);
            for_each_bit(m, |x, y, z| {
                out.push([b[0] * 8 + x, b[1] * 8 + y, b[2] * 8 + z])
            });
        }
        out
    }
}

/// Marker for "no member" in a [`Numbered::fill_window`] window.
pub const NO_ID: u32 = u32::MAX;

/// Index into a 9³ window: local coordinates 0..=8 per axis.
#[inline]
pub fn window_index(x: u32, y: u32, z: u32) -> usize {
    (x + 9 * y + 81 * z) as usize
}

impl Numbered {
    /// Fills `out` with the numbers of the members at `8·b + (0..=8)³` (or [`NO_ID`]): a brick
    /// and the first layer of its +x, +y, +z neighbours, so that every corner of every cell of
    /// brick `b` is one array read away.
    pub fn fill_window(&self, b: [u32; 3], out: &mut [u32; 729]) {
        out.fill(NO_ID);
        for d in 0..8u32 {
            let (dx, dy, dz) = (d & 1, (d >> 1) & 1, d >> 2);
            let nb = [(b[0] + dx) as i64, (b[1] + dy) as i64, (b[2] + dz) as i64];
            let Some(s) = self.set.index.slot(nb) else {
                continue;
            };
            let m = &self.set.masks[s];
            // In a neighbour only local coordinate 0 along each shifted axis is in the window.
            let mut keep = [u64::MAX; 8];
            for (z, k) in keep.iter_mut().enumerate() {
                if dz == 1 && z > 0 {
                    *k = 0;
                }
                if dx == 1 {
                    *k &= X0;
                }
                if dy == 1 {
                    *k &= Y0;
                }
            }
            let mut before = self.offsets[s];
            for z in 0..8 {
                let word = m[z];
                let mut w = word & keep[z];
                while w != 0 {
                    let bit = w.trailing_zeros();
                    let id = before + (word & ((1u64 << bit) - 1)).count_ones();
                    out[window_index((bit & 7) + 8 * dx, (bit >> 3) + 8 * dy, z as u32 + 8 * dz)] =
                        id;
                    w &= w - 1;
                }
                before += word.count_ones();
            }
        }
    }
}

impl Numbered {
    /// Runs `f(scratch, slot, brick coordinate, mask, out)` for every brick in parallel, where
    /// `slot` is the brick's position in the set (its first member is `offsets[slot]`), `out`
    /// is the brick's own slice of a flat per-member array (members in local bit order) and
    /// `scratch` a per-thread value made by `init`. Writes land in place: no per-brick vectors
    /// to collect and concatenate.
    pub fn par_fill<T: Send, S>(
        &self,
        data: &mut [T],
        init: impl Fn() -> S + Sync + Send,
        f: impl Fn(&mut S, usize, [u32; 3], &BrickMask, &mut [T]) + Sync + Send,
    ) {
        use rayon::prelude::*;
        let mut parts: Vec<(usize, &mut [T])> = Vec::with_capacity(self.set.keys.len());
        let mut rest = data;
        for (s, m) in self.set.masks.iter().enumerate() {
            let (head, tail) = rest.split_at_mut(count(m) as usize);
            parts.push((s, head));
            rest = tail;
        }
        parts
            .into_par_iter()
            .for_each_init(init, |scratch, (s, out)| {
                let b = self.set.index.coord(self.set.keys[s] as usize);
                f(scratch, s, b, &self.set.masks[s], out)
            });
    }

    /// Sets `data[id] = f(id, coordinate)` for every member, in parallel over bricks.
    pub fn par_fill_each<T: Send>(
        &self,
        data: &mut [T],
        f: impl Fn(usize, [u32; 3]) -> T + Sync + Send,
    ) {
        self.par_fill(
            data,
            || (),
            |_, s, b, mask, out| {
                let first = self.offsets[s] as usize;
                let mut i = 0;
                for_each_bit(mask, |x, y, z| {
                    out[i] = f(first + i, [b[0] * 8 + x, b[1] * 8 + y, b[2] * 8 + z]);
                    i += 1;
                });
            },
        );
    }

    /// Coordinates of the members with the given numbers (each below `len`, in any order),
    /// without materialising every member's coordinates: ascending numbers walk the bricks
    /// forward, a smaller one than the last is found by bisection.
    pub fn coords_of(&self, ids: &[u32]) -> Vec<[u32; 3]> {
        let mut out = Vec::with_capacity(ids.len());
        let mut s = 0;
        for &id in ids {
            if id < self.offsets[s] {
                // The last brick whose first member is at most `id` (brick 0's is 0).
                s = self.offsets.partition_point(|&first| first <= id) - 1;
            }
            while s + 1 < self.offsets.len() && self.offsets[s + 1] <= id {
                s += 1;
            }
            let b = self.set.index.coord(self.set.keys[s] as usize);
            let local = nth_bit(&self.set.masks[s], id - self.offsets[s]);
            out.push([
                b[0] * 8 + (local & 7),
                b[1] * 8 + ((local >> 3) & 7),
                b[2] * 8 + (local >> 6),
            ]);
        }
        out
    }
}

/// Local index (x + 8y + 64z) of the `n`-th set bit of a mask (which has more than `n`).
pub fn nth_bit(m: &BrickMask, mut n: u32) -> u32 {
    for (z, &word) in m.iter().enumerate() {
        let c = word.count_ones();
        if n < c {
            let mut w = word;
            for _ in 0..n {
                w &= w - 1;
            }
            return 64 * z as u32 + w.trailing_zeros();
        }
        n -= c;
    }
    0
}

impl BrickSet {
    /// Every member's coordinates in lexicographic (x, y, z) order, as `u16` (coordinates are
    /// at most [`crate::params::MAX_RESOLUTION`]). Generated slab by slab (bricks sharing a
    /// brick x coordinate) in parallel straight into the output, without a global sort: each
    /// brick's mask is first transposed into 64 column bytes (one per local (x, y), a bit per
    /// local z), so the walk visits members, not all 512 positions.
    pub fn sorted_members(&self) -> Vec<[u16; 3]> {
        use rayon::prelude::*;
        let mut bricks: Vec<([u32; 3], usize)> = self
            .keys
            .iter()
            .enumerate()
            .map(|(s, &k)| (self.index.coord(k as usize), s))
            .collect();
        bricks.sort_unstable();
        let mut slabs: Vec<&[([u32; 3], usize)]> = Vec::new();
        let mut rest = &bricks[..];
        while let Some(first) = rest.first() {
            let len = rest.iter().take_while(|b| b.0[0] == first.0[0]).count();
            let (slab, tail) = rest.split_at(len);
            slabs.push(slab);
            rest = tail;
        }
        let sizes: Vec<usize> = slabs
            .iter()
            .map(|slab| {
                slab.iter()
                    .map(|&(_, s)| count(&self.masks[s]) as usize)
                    .sum()
            })
            .collect();
        let mut out = vec![[0u16; 3]; sizes.iter().sum()];
        let mut parts = Vec::with_capacity(slabs.len());
        let mut tail = &mut out[..];
        for (slab, &size) in slabs.iter().zip(&sizes) {
            let (head, rest) = tail.split_at_mut(size);
            parts.push((*slab, head));
            tail = rest;
        }
        parts.into_par_iter().for_each(|(slab, out)| {
            let columns: Vec<[u8; 64]> = slab
                .iter()
                .map(|&(_, s)| {
                    let mut col = [0u8; 64];
                    for (z, &word) in self.masks[s].iter().enumerate() {
                        let mut w = word;
                        while w != 0 {
                            col[w.trailing_zeros() as usize] |= 1 << z;
                            w &= w - 1;
                        }
                    }
                    col
                })
                .collect();
            // Rows: runs of bricks sharing (bx, by), ascending bz (positions in `slab`).
            let mut rows: Vec<std::ops::Range<usize>> = Vec::new();
            let mut start = 0;
            while start < slab.len() {
                let by = slab[start].0[1];
                let len = slab[start..].iter().take_while(|b| b.0[1] == by).count();
                rows.push(start..start + len);
                start += len;
            }
            let mut i = 0;
            for lx in 0..8u32 {
                for row in &rows {
                    for ly in 0..8u32 {
                        for p in row.clone() {
                            let b = slab[p].0;
                            let mut col = columns[p][(lx + 8 * ly) as usize];
                            while col != 0 {
                                let lz = col.trailing_zeros();
                                out[i] = [
                                    (b[0] * 8 + lx) as u16,
                                    (b[1] * 8 + ly) as u16,
                                    (b[2] * 8 + lz) as u16,
                                ];
                                i += 1;
                                col &= col - 1;
                            }
                        }
                    }
                }
            }
        });
        out
    }
}
