//! The enclosed regions as the inside test found them ([`Regions`]): which region a cell or a
//! vertex lies in, their verdicts and counts, and the air (and unsealed) regions handed to the
//! flood's outside ([`mark_air`]).

use super::vote::Verdict;
use crate::grid::{cube_offsets, BrickMask, BrickSet, NO_BRICK};
use crate::stages::band::Band;
use crate::stages::flood::Flood;
use crate::stages::vertex_side::open_neighbours;
use crate::stages::voxelize::Voxelization;

/// Steps through unblocked grid edges [`Regions::region_at`] takes to find an enclosed cell.
pub const REGION_SEARCH: usize = 2;

/// Region marker for "no region".
pub const NO_REGION: u32 = u32::MAX;

/// The enclosed regions with their winding numbers and verdicts.
#[derive(Debug, Clone, Default)]
pub struct Regions {
    /// Per wall brick (parallel to the walls' bricks), its first part in `parts`; one more
    /// entry at the end.
    pub(super) part_starts: Vec<u32>,
    /// Connected parts of the enclosed cells of wall bricks: (cells, region).
    pub(super) parts: Vec<(BrickMask, u32)>,
    /// Bricks without wall cells that the flood does not reach: (brick key, region), by key.
    pub(super) empty: Vec<(u32, u32)>,
    /// Per region: the median |w| of its samples.
    pub winding: Vec<f64>,
    /// Per region: what that says.
    pub verdicts: Vec<Verdict>,
}

/// Counts of a classification, for the conversion's summary.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RegionCounts {
    /// Enclosed regions.
    pub regions: u64,
    /// Of those, air.
    pub air: u64,
    /// Of those, ambiguous (kept solid).
    pub ambiguous: u64,
}

impl Regions {
    /// The region of cell `c` if it is an enclosed cell.
    pub fn region_of(&self, walls: &BrickSet, c: [i64; 3]) -> Option<u32> {
        if c.iter().any(|&v| v < 0) {
            return None;
        }
        let (b, w, bit) = crate::grid::split([c[0] as u32, c[1] as u32, c[2] as u32]);
        let index = &walls.index;
        if (0..3).any(|a| b[a] >= index.dims[a]) {
            return None;
        }
        let key = index.key(b);
        match index.slots[key] {
            NO_BRICK => self
                .empty
                .binary_search_by_key(&(key as u32), |e| e.0)
                .ok()
                .map(|i| self.empty[i].1),
            s => {
                let s = s as usize;
                let range = self.part_starts[s] as usize..self.part_starts[s + 1] as usize;
                self.parts[range]
                    .iter()
                    .find(|(m, _)| (m[w] >> bit) & 1 == 1)
                    .map(|p| p.1)
            }
        }
    }

    /// The enclosed region vertex `c` lies in: that of a surface-free enclosed cell it is a
    /// corner of (the smallest number if several), else the nearest one found through grid
    /// edges no triangle crosses within [`REGION_SEARCH`] steps (a vertex whose cells all
    /// touch the surface); `None` if there is none.
    pub fn region_at(&self, band: &Band, vox: &Voxelization, c: [i64; 3]) -> Option<u32> {
        // Most vertices are a corner of an enclosed cell: no search, no allocation.
        let first = (0..8i64)
            .map(|d| [c[0] - (d & 1), c[1] - ((d >> 1) & 1), c[2] - (d >> 2)])
            .filter_map(|cell| self.region_of(&vox.walls, cell))
            .min();
        if first.is_some() {
            return first;
        }
        let mut seen = vec![c];
        let mut frontier = vec![c];
        for _ in 0..=REGION_SEARCH {
            let found = frontier
                .iter()
                .flat_map(|v| {
                    (0..8i64).map(move |d| [v[0] - (d & 1), v[1] - ((d >> 1) & 1), v[2] - (d >> 2)])
                })
                .filter_map(|cell| self.region_of(&vox.walls, cell))
                .min();
            if found.is_some() {
                return found;
            }
            let mut next = Vec::new();
            for v in &frontier {
                if v.iter().any(|&x| x < 0) {
                    continue;
                }
                for (_, u) in open_neighbours(band, vox, v.map(|x| x as u32)) {
                    let u = u.map(|x| x as i64);
                    if !seen.contains(&u) {
                        seen.push(u);
                        next.push(u);
                    }
                }
            }
            frontier = next;
        }
        None
    }

    /// Per brick key of `walls`' index: whether the brick, or one of its 26 neighbours, holds
    /// cells of a region `marked`.
    pub(super) fn bricks_near(&self, walls: &BrickSet, marked: &[bool]) -> Vec<bool> {
        let index = &walls.index;
        let mut holds = vec![false; index.slots.len()];
        for s in 0..walls.keys.len() {
            let range = self.part_starts[s] as usize..self.part_starts[s + 1] as usize;
            if self.parts[range].iter().any(|&(_, r)| marked[r as usize]) {
                holds[walls.keys[s] as usize] = true;
            }
        }
        for &(key, r) in &self.empty {
            if marked[r as usize] {
                holds[key as usize] = true;
            }
        }
        let mut near = holds.clone();
        for key in (0..holds.len()).filter(|&k| holds[k]) {
            let b = index.coord(key);
            for off in cube_offsets(1) {
                let nb: [i64; 3] = std::array::from_fn(|a| b[a] as i64 + off[a]);
                if (0..3).all(|a| nb[a] >= 0 && (nb[a] as u32) < index.dims[a]) {
                    near[index.key(nb.map(|v| v as u32))] = true;
                }
            }
        }
        near
    }

    /// Whether region `r` goes to the outside: air, or unsealed.
    #[inline]
    pub fn is_outside(&self, r: u32) -> bool {
        matches!(self.verdicts[r as usize], Verdict::Air | Verdict::Unsealed)
    }

    /// The regions of the cells `sealed` (one in each region a sealing made, stage 4) that do not
    /// read as solid are unsealed; returns how many sealed regions stay (distinct, solid).
    pub fn unseal_unless_solid(&mut self, walls: &BrickSet, sealed: &[[i64; 3]]) -> u64 {
        let mut kept: Vec<u32> = Vec::new();
        for &c in sealed {
            let Some(r) = self.region_of(walls, c) else {
                continue;
            };
            match self.verdicts[r as usize] {
                Verdict::Solid => kept.push(r),
                _ => self.verdicts[r as usize] = Verdict::Unsealed,
            }
        }
        kept.sort_unstable();
        kept.dedup();
        kept.len() as u64
    }

    /// How many regions, air regions and ambiguous ones.
    pub fn counts(&self) -> RegionCounts {
        let of = |v: Verdict| self.verdicts.iter().filter(|&&x| x == v).count() as u64;
        RegionCounts {
            regions: self.verdicts.len() as u64,
            air: of(Verdict::Air),
            ambiguous: of(Verdict::Ambiguous),
        }
    }
}

/// Adds the cells of every air (and unsealed) region to the flood's outside.
pub fn mark_air(flood: &mut Flood, walls: &BrickSet, regions: &Regions) {
    for s in 0..walls.keys.len() {
        let range = regions.part_starts[s] as usize..regions.part_starts[s + 1] as usize;
        for (m, r) in &regions.parts[range] {
            if regions.is_outside(*r) {
                for z in 0..8 {
                    flood.wall_outside[s][z] |= m[z];
                }
            }
        }
    }
    for &(key, r) in &regions.empty {
        if regions.is_outside(r) {
            flood.empty_outside[key as usize] = true;
        }
    }
}
