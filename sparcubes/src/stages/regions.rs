//! Stage 3b: the enclosed regions, each decided solid or air by the source's winding number.
//!
//! The flood ([`crate::stages::flood`]) reaches every surface-free cell joined to the grid's border;
//! the rest form *enclosed regions*: connected sets (through cell faces) of surface-free cells
//! the flood cannot reach. Reachability alone would call them all solid, but whether a region
//! is material or air is a property of the source: the inside of a cube's cavity, or the space
//! between a double-walled hull and the parts it holds, is enclosed and empty. So every region
//! is decided by the generalised winding number |w| of the source ([`crate::queries::winding`]), sampled
//! at a few of its cells (the median of [`SAMPLES`]): solid for |w| ≥ [`SOLID_FROM`], air for
//! |w| ≤ [`AIR_UP_TO`]. A region in between is *ambiguous* (an inconsistently oriented soup,
//! overlapping open sheets) and keeps what reachability says: solid, the behaviour without the
//! test. |w| rather than w, so a mesh oriented inwards throughout reads as it does outwards.
//!
//! Air regions are then treated as outside: [`mark_air`] adds their cells to the flood's
//! outside, so a surface between the outside (or air) and a solid region keeps its exact
//! position, and the parts inside a hollow hull come out as closed surfaces of their own.
//!
//! Regions are found brick by brick without a per-cell pass over the grid: inside a brick with
//! wall cells, its surface-free cells not reached by the flood are split into connected parts
//! by bit-parallel growth; a brick without wall cells is one part; parts touching across brick
//! faces are joined with a union–find whose roots are the smallest part numbers, so regions
//! and their numbering do not depend on thread count.

use crate::grid::{
    count, cube_offsets, dilate, face_carry, for_each_bit, is_empty, nth_bit, BrickMask, BrickSet,
    Dilation, NO_BRICK,
};
use crate::queries::winding::{LazyWindingTree, WindingTree};
use crate::stages::band::Band;
use crate::stages::flood::{grow_within, Flood, FULL};
use crate::stages::sign::{open_neighbours, Side};
use crate::stages::voxelize::Voxelization;
use rayon::prelude::*;

/// Winding numbers sampled per region (or per sealed group of vertices); the median decides.
pub const SAMPLES: usize = 3;

/// |w| at or below which a region is air.
pub const AIR_UP_TO: f64 = 0.25;

/// |w| at or above which a region is solid.
pub const SOLID_FROM: f64 = 0.75;

/// What the winding number says of a region.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// |w| ≥ [`SOLID_FROM`]: material.
    Solid,
    /// |w| ≤ [`AIR_UP_TO`]: empty space.
    Air,
    /// In between: the caller keeps the answer the grid alone gives.
    Ambiguous,
    /// A region sealed behind small openings (docs/ALGORITHM.md §3b) that is not read as
    /// solid here: back to the outside, the answer of the grid's exact flood.
    Unsealed,
}

/// The verdict for a (median) winding number.
pub fn verdict(w: f64) -> Verdict {
    let w = w.abs();
    if w >= SOLID_FROM {
        Verdict::Solid
    } else if w <= AIR_UP_TO {
        Verdict::Air
    } else {
        Verdict::Ambiguous
    }
}

/// The median of |w| at the given points (empty: 0); `stack` is the queries' scratch space.
pub fn median_winding(tree: &WindingTree, points: &[[f64; 3]], stack: &mut Vec<u32>) -> f64 {
    let mut w: Vec<f64> = points
        .iter()
        .map(|&p| tree.winding_number_with(p, stack).abs())
        .collect();
    median(&mut w)
}

fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    let m = values.len() / 2;
    if values.len() % 2 == 1 {
        values[m]
    } else {
        0.5 * (values[m - 1] + values[m])
    }
}

/// Smallest difference of |w| between two regions for one to be nested in the other: half
/// the step of one closed surface.
pub const NESTED_STEP: f64 = 0.5;

/// Steps through unblocked grid edges [`Regions::region_at`] takes to find an enclosed cell.
pub const REGION_SEARCH: usize = 2;

/// Region marker for "no region".
pub const NO_REGION: u32 = u32::MAX;

/// The enclosed regions with their winding numbers and verdicts.
#[derive(Debug, Clone, Default)]
pub struct Regions {
    /// Per wall brick (parallel to the walls' bricks), its first part in `parts`; one more
    /// entry at the end.
    part_starts: Vec<u32>,
    /// Connected parts of the enclosed cells of wall bricks: (cells, region).
    parts: Vec<(BrickMask, u32)>,
    /// Bricks without wall cells that the flood does not reach: (brick key, region), by key.
    empty: Vec<(u32, u32)>,
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
    fn bricks_near(&self, walls: &BrickSet, marked: &[bool]) -> Vec<bool> {
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

    /// The regions of the cells `sealed` (one in each region a sealing made, §3b) that do not
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

/// The rule for surfaces between two solid regions, prepared once per conversion: which
/// enclosed region each end of a crossed grid edge between two inside vertices lies in, and
/// which regions are *wholly nested*.
///
/// A region is wholly nested when the surfaces around it separate it (through crossed grid
/// edges between inside vertices) from exactly one other solid region, of a winding number
/// lower by at least [`NESTED_STEP`], and from nothing else (no crossed edge leads from it to
/// an outside vertex, and no outside vertex lies within [`NESTED_CLEARANCE`] of it): a solid
/// modelled entirely inside another (a sphere in a sphere), whose surface bounds no material
/// and is not kept. Where two closed parts only
/// overlap (a leg pushed into a body), the overlap is separated from two regions (the leg's
/// own inside and the body's), and the surfaces inside it are the parts' own: they stay, as
/// thin sheets inside the solid, as without the rule. Removing them cut each part back to what
/// shows outside the other, which lost parts and recall on the dev corpus (docs/ALGORITHM.md
/// §2b).
#[derive(Debug, Clone, Default)]
pub struct Nesting {
    /// Per core band vertex: its solid enclosed region if it is an inside end of a crossed
    /// edge between two inside vertices, else [`NO_REGION`]. Empty when no two solid regions
    /// differ enough to be nested.
    region: Vec<u32>,
    /// Per region: wholly nested in another.
    wholly: Vec<bool>,
    /// Per region: its median |w|.
    winding: Vec<f64>,
}

/// Distance, in grid steps per axis, from the inside ends of a nested region's crossed edges
/// within which no vertex may be outside for the region to be wholly nested. Where an inner
/// solid reaches the other's wall or pokes out of it by less than the grid resolves, the part
/// outside holds no enclosed cell, so no crossed edge leads from the region to an outside
/// vertex, yet removing the region's surface removes what shows outside too, with the open
/// pieces (decals, caps) lying on it. On the dev corpus `Airport_Pushback_Forklift.glb` kept
/// 90 of 96 components at 512³ with the rule unguarded, 92 with 2 steps, 95 with 3, 96 (as
/// without the inside test) with 4 (docs/QUALITY.md, issue 15).
pub const NESTED_CLEARANCE: i64 = 4;

/// The wholly nested regions (of `region`, per band vertex) with an outside vertex within
/// [`NESTED_CLEARANCE`] steps per axis of an end of one of `edges` in them; a region may
/// appear more than once.
fn near_outside(
    band: &Band,
    side: &[Side],
    edges: &[(u32, u32, [i64; 3], [i64; 3])],
    region: &[u32],
    wholly: &[bool],
) -> Vec<u32> {
    edges
        .par_iter()
        .flat_map_iter(|&(i, j, v, u)| [(i, v), (j, u)])
        .filter_map(|(i, c)| {
            let r = region[i as usize];
            if r == NO_REGION || !wholly[r as usize] {
                return None;
            }
            cube_offsets(NESTED_CLEARANCE)
                .any(|off| {
                    let q: [i64; 3] = std::array::from_fn(|a| c[a] + off[a]);
                    band.verts
                        .id(q)
                        .is_some_and(|k| side[k as usize] == Side::Outside)
                })
                .then_some(r)
        })
        .collect()
}

/// Calls `f(v, u)` for every crossed grid edge (from `v` to `u` = `v` + one step along an
/// axis) whose lower end `v` lies in a brick `near` holds (indexed by `walls`' brick keys),
/// brick by brick in parallel, and gathers what it returns.
fn map_blocked_edges<T: Send>(
    vox: &Voxelization,
    near: &[bool],
    f: impl Fn([i64; 3], [i64; 3], &mut Vec<T>) + Sync,
) -> Vec<T> {
    let index = &vox.walls.index;
    vox.blocked
        .par_iter()
        .enumerate()
        .flat_map(|(axis, set)| {
            (0..set.keys.len())
                .into_par_iter()
                .filter(move |&s| {
                    let b = set.index.coord(set.keys[s] as usize);
                    (0..3).all(|a| b[a] < index.dims[a]) && near[index.key(b)]
                })
                .map(move |s| (axis, set, s))
        })
        .flat_map_iter(|(axis, set, s)| {
            let mut out = Vec::new();
            set.for_each_member(s, |v| {
                let mut u = v;
                u[axis] += 1;
                f(v, u, &mut out);
            });
            out
        })
        .collect()
}

impl Nesting {
    /// Finds the regions at the ends of crossed edges between inside vertices and the wholly
    /// nested regions (`side`: every band vertex's side, none `Unknown`). Costs nothing unless
    /// two solid regions differ by [`NESTED_STEP`] or more.
    pub fn new(band: &Band, vox: &Voxelization, side: &[Side], regions: &Regions) -> Self {
        let solid = |r: u32| regions.verdicts[r as usize] == Verdict::Solid;
        let (lo, hi) = (0..regions.verdicts.len() as u32)
            .filter(|&r| solid(r))
            .map(|r| regions.winding[r as usize])
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), w| {
                (lo.min(w), hi.max(w))
            });
        if hi - lo < NESTED_STEP {
            return Self::default();
        }
        // Only a region at least NESTED_STEP above the lowest solid one can be the inner one
        // of a nested pair, and the edges on its surface lie within a brick of its cells
        // (`region_at` looks at most REGION_SEARCH + 1 < 8 cells away): the crossed edges
        // elsewhere (most of the surface) separate no nested pair and are skipped.
        let inner: Vec<bool> = (0..regions.verdicts.len() as u32)
            .map(|r| solid(r) && regions.winding[r as usize] - lo >= NESTED_STEP)
            .collect();
        let near_inner = regions.bricks_near(&vox.walls, &inner);
        // The crossed edges between two inside vertices there, as band vertex numbers, and
        // their ends with coordinates.
        let edges: Vec<(u32, u32, [i64; 3], [i64; 3])> =
            map_blocked_edges(vox, &near_inner, |v, u, out| {
                if let (Some(i), Some(j)) = (band.verts.id(v), band.verts.id(u)) {
                    if side[i as usize] == Side::Inside && side[j as usize] == Side::Inside {
                        out.push((i, j, v, u));
                    }
                }
            });
        let mut ends: Vec<(u32, [i64; 3])> = edges
            .par_iter()
            .flat_map_iter(|&(i, j, v, u)| [(i, v), (j, u)])
            .collect();
        ends.par_sort_unstable();
        ends.dedup();
        let found: Vec<u32> = ends
            .par_iter()
            .map(|&(_, c)| {
                regions
                    .region_at(band, vox, c)
                    .filter(|&r| solid(r))
                    .unwrap_or(NO_REGION)
            })
            .collect();
        let mut region = vec![NO_REGION; side.len()];
        for (&(i, _), &r) in ends.iter().zip(&found) {
            region[i as usize] = r;
        }
        let winding = regions.winding.clone();
        // (higher region, lower region) for every edge between regions nested one in the other.
        let mut pairs: Vec<(u32, u32)> = edges
            .par_iter()
            .filter_map(|&(i, j, _, _)| {
                let (a, b) = (region[i as usize], region[j as usize]);
                if a == NO_REGION || b == NO_REGION {
                    return None;
                }
                let (wa, wb) = (winding[a as usize], winding[b as usize]);
                if wa - wb >= NESTED_STEP {
                    Some((a, b))
                } else if wb - wa >= NESTED_STEP {
                    Some((b, a))
                } else {
                    None
                }
            })
            .collect();
        pairs.par_sort_unstable();
        pairs.dedup();
        let mut wholly = vec![false; winding.len()];
        for group in pairs.chunk_by(|a, b| a.0 == b.0) {
            wholly[group[0].0 as usize] = group.len() == 1;
        }
        // A region near an outside vertex may poke out of the other through a part too thin
        // for enclosed cells: not wholly inside it.
        if wholly.contains(&true) {
            for r in near_outside(band, side, &edges, &region, &wholly) {
                wholly[r as usize] = false;
            }
        }
        // A region with a crossed edge to an outside vertex is not wholly inside another.
        if wholly.contains(&true) {
            // Only edges within a brick of a wholly nested region's cells can lead from it
            // (`region_at` looks at most REGION_SEARCH + 1 < 8 cells away): most of the
            // surface's crossed edges are skipped without a region look-up.
            let near = regions.bricks_near(&vox.walls, &wholly);
            let touching: Vec<u32> = map_blocked_edges(vox, &near, |v, u, out| {
                let (Some(i), Some(j)) = (band.verts.id(v), band.verts.id(u)) else {
                    return;
                };
                let inner = match (side[i as usize], side[j as usize]) {
                    (Side::Inside, Side::Outside) => v,
                    (Side::Outside, Side::Inside) => u,
                    _ => return,
                };
                if let Some(r) = regions.region_at(band, vox, inner) {
                    if wholly[r as usize] {
                        out.push(r);
                    }
                }
            });
            for r in touching {
                wholly[r as usize] = false;
            }
        }
        Self {
            region,
            wholly,
            winding,
        }
    }

    /// Whether the crossed grid edge between band vertices `i` and `j` (both inside) is on
    /// the surface of a wholly nested region, where it meets the one region it is nested in.
    #[inline]
    pub fn separates(&self, i: u32, j: u32) -> bool {
        if self.region.is_empty() {
            return false;
        }
        let (a, b) = (self.region[i as usize], self.region[j as usize]);
        if a == NO_REGION || b == NO_REGION || a == b {
            return false;
        }
        let (wa, wb) = (self.winding[a as usize], self.winding[b as usize]);
        let inner = if wa > wb { a } else { b };
        (wa - wb).abs() >= NESTED_STEP && self.wholly[inner as usize]
    }
}

/// Splits the enclosed cells of every wall brick into connected parts (within the brick).
fn wall_parts(walls: &BrickSet, flood: &Flood) -> (Vec<u32>, Vec<BrickMask>) {
    let per_brick: Vec<Vec<BrickMask>> = (0..walls.keys.len())
        .into_par_iter()
        .map(|s| {
            let wall = &walls.masks[s];
            let outside = &flood.wall_outside[s];
            let mut left: BrickMask = std::array::from_fn(|z| !(wall[z] | outside[z]));
            let mut parts = Vec::new();
            while let Some(z) = left.iter().position(|&w| w != 0) {
                let mut part = [0u64; 8];
                part[z] = left[z] & left[z].wrapping_neg();
                let blocked: BrickMask = std::array::from_fn(|k| !left[k]);
                grow_within(&mut part, &blocked);
                for k in 0..8 {
                    left[k] &= !part[k];
                }
                parts.push(part);
            }
            parts
        })
        .collect();
    let mut starts = Vec::with_capacity(per_brick.len() + 1);
    let mut parts = Vec::new();
    for p in per_brick {
        starts.push(parts.len() as u32);
        parts.extend(p);
    }
    starts.push(parts.len() as u32);
    (starts, parts)
}

/// Union–find over part numbers; the root of a set is its smallest member.
/// A union–find over `0..n` whose roots are the smallest members of their sets (path
/// halving; a union links the larger root under the smaller).
pub(crate) struct Sets(Vec<u32>);

impl Sets {
    /// Every member in a set of its own.
    pub(crate) fn new(n: usize) -> Self {
        Self((0..n as u32).collect())
    }

    /// The root of `x`'s set.
    pub(crate) fn find(&mut self, mut x: u32) -> u32 {
        while self.0[x as usize] != x {
            let up = self.0[self.0[x as usize] as usize];
            self.0[x as usize] = up;
            x = up;
        }
        x
    }

    /// Joins the sets of `a` and `b`.
    pub(crate) fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            let (lo, hi) = (ra.min(rb), ra.max(rb));
            self.0[hi as usize] = lo;
        }
    }
}

/// Distances, in voxels, past a wall's closest point at which [`across_walls`] reads the
/// winding number: just past it (far above the rounding of the stored closest points, f32),
/// and one cell deep. Material just past the wall tells a wall from a surface modelled
/// two-sided as coincident faces (the copies cancel, so |w| is 0 on both sides). Material a
/// cell deep tells a wall that holds grid vertices, whose surfaces both keep their exact
/// position with the region as air, from a thinner one, which would come out as a thin shell
/// around both surfaces (offset about 0.9 voxel), worse than the solid that reachability makes
/// of it (on the dev corpus at 256³, `shippingContainer.obj`'s sub-voxel walls went from F1
/// 81.6 to 61.2 with its inside as air). Either check alone fails on the dev corpus: the deep
/// one can land in another part behind a two-sided wall (`painted-bench.obj`).
pub const ACROSS: [f64; 2] = [0.01, 1.0];

/// Median |w| across a wall ([`ACROSS`]) from which it counts as material: above
/// [`SOLID_FROM`], because a wall that is solid for a cell deep reads close to 1 there, and
/// on the dev corpus at 256³ the air regions whose walls read between 0.75 and 0.9
/// (`samurai_monastry.obj`: 0.75, 0.81, 0.86) cost F1 (79.4 → 76.2 with them as air, 78.9
/// with them solid); the walls of the regions that gain from being air read 1.00–1.07.
pub const WALL_FROM: f64 = 0.9;

/// Fewest cells an air region needs to be air. A smaller pocket (a cell or a few, between
/// layered surfaces such as clothes over a body) would come out as a bubble the grid cannot
/// shape; on the dev corpus at 256³ `girlStanding.obj`'s 18 one-cell air pockets cost 0.4 F1
/// and the air regions that gain are hundreds of cells or more. Such a pocket is ambiguous:
/// solid, as reachability says.
pub const AIR_MIN_CELLS: u64 = 8;

/// Per region to check (`wanted`), the median |w| across its wall: at up to [`SAMPLES`]
/// band vertices at corners of its cells (first found in part order, each farther than 10⁻³
/// voxel from the surface), the points [`ACROSS`] voxel past the vertex's closest surface
/// point, away from the vertex; the smaller of the two depths' medians. Regions without such
/// a vertex get `None`.
fn across_walls(
    band: &Band,
    parts: &[(BrickMask, u32)],
    part_keys: &dyn Fn(u32) -> u32,
    index: &crate::grid::BrickIndex,
    wanted: &[bool],
    tree: &WindingTree,
) -> Vec<Option<f64>> {
    let mut found: Vec<Vec<u32>> = vec![Vec::new(); wanted.len()];
    for (p, (mask, r)) in parts.iter().enumerate() {
        let r = *r as usize;
        if !wanted[r] || found[r].len() >= SAMPLES {
            continue;
        }
        let b = index.coord(part_keys(p as u32) as usize);
        let list = &mut found[r];
        for_each_bit(mask, |x, y, z| {
            for d in 0..8u32 {
                if list.len() >= SAMPLES {
                    return;
                }
                let c = [
                    (b[0] * 8 + x + (d & 1)) as i64,
                    (b[1] * 8 + y + ((d >> 1) & 1)) as i64,
                    (b[2] * 8 + z + (d >> 2)) as i64,
                ];
                if let Some(i) = band.verts.id(c) {
                    if band.nearest[i as usize].udf > 1e-3 && !list.contains(&i) {
                        list.push(i);
                    }
                }
            }
        });
    }
    found
        .par_iter()
        .map_init(
            || Vec::with_capacity(64),
            |stack, ids| {
                if ids.is_empty() {
                    return None;
                }
                let coords = band.verts.coords_of(ids);
                let depth = |d: f64| -> Vec<[f64; 3]> {
                    ids.iter()
                        .zip(&coords)
                        .map(|(&i, c)| {
                            let near = &band.nearest[i as usize];
                            let q = near.point.map(|v| v as f64);
                            let away: [f64; 3] = std::array::from_fn(|a| q[a] - c[a] as f64);
                            let len = crate::vec3::dot(away, away).sqrt();
                            std::array::from_fn(|a| q[a] + d * away[a] / len)
                        })
                        .collect()
                };
                let shallow = median_winding(tree, &depth(ACROSS[0]), stack);
                let deep = median_winding(tree, &depth(ACROSS[1]), stack);
                Some(shallow.min(deep))
            },
        )
        .collect()
}

/// Finds the enclosed regions of `flood` (over `walls`) and decides each with `tree`.
///
/// A region that reads as air (|w| ≤ [`AIR_UP_TO`]) is air only if there is material across
/// its wall, from just past it to a cell deep: |w| at both distances of [`ACROSS`] past the
/// wall ([`across_walls`]) at least [`SOLID_FROM`]. Where it is not, the wall is thinner than a cell, or a surface modelled
/// two-sided as coincident faces of both orientations (a box of double faces: the copies
/// cancel, so |w| is 0 inside and out), and the region is ambiguous: solid, as reachability
/// says.
pub fn classify_regions(
    walls: &BrickSet,
    flood: &Flood,
    band: &Band,
    tree: &LazyWindingTree,
) -> Regions {
    let index = &walls.index;
    let (part_starts, masks) = wall_parts(walls, flood);
    let empty_keys: Vec<u32> = (0..index.slots.len() as u32)
        .filter(|&k| index.slots[k as usize] == NO_BRICK && !flood.empty_outside[k as usize])
        .collect();
    let wall_count = masks.len() as u32;
    let total = wall_count as usize + empty_keys.len();
    if total == 0 {
        return Regions {
            part_starts,
            ..Regions::default()
        };
    }
    // Part numbers: wall parts first (by brick slot, then part), then empty bricks by key.
    let part_of_empty = |key: u32| -> Option<u32> {
        empty_keys
            .binary_search(&key)
            .ok()
            .map(|i| wall_count + i as u32)
    };
    let mut sets = Sets((0..total as u32).collect());
    let mask_of = |p: u32| -> BrickMask {
        if p < wall_count {
            masks[p as usize]
        } else {
            FULL
        }
    };
    let key_of = |p: u32| -> u32 {
        if p < wall_count {
            let s = part_starts.partition_point(|&st| st <= p) - 1;
            walls.keys[s]
        } else {
            empty_keys[(p - wall_count) as usize]
        }
    };
    // Join parts across the +x, +y, +z face of their brick (each face pair once).
    for p in 0..total as u32 {
        let key = key_of(p);
        let b = index.coord(key as usize);
        let mask = mask_of(p);
        for axis in 0..3 {
            if b[axis] + 1 >= index.dims[axis] {
                continue;
            }
            let carry = face_carry(&mask, axis, true);
            if is_empty(&carry) {
                continue;
            }
            let mut nb = b;
            nb[axis] += 1;
            let nkey = index.key(nb) as u32;
            match index.slots[nkey as usize] {
                NO_BRICK => {
                    if let Some(q) = part_of_empty(nkey) {
                        sets.union(p, q);
                    }
                }
                s => {
                    let s = s as usize;
                    for q in part_starts[s]..part_starts[s + 1] {
                        let m = &masks[q as usize];
                        if (0..8).any(|z| carry[z] & m[z] != 0) {
                            sets.union(p, q);
                        }
                    }
                }
            }
        }
    }
    // Regions numbered by their smallest part.
    let mut region_of_part = vec![NO_REGION; total];
    let mut regions = 0u32;
    for p in 0..total as u32 {
        let root = sets.find(p);
        if root == p {
            region_of_part[p as usize] = regions;
            regions += 1;
        } else {
            region_of_part[p as usize] = region_of_part[root as usize];
        }
    }
    let points = sample_points(
        regions as usize,
        &region_of_part,
        wall_count,
        &mask_of,
        &key_of,
        index,
    );
    let tree = tree.get();
    let winding: Vec<f64> = points
        .par_iter()
        .map_init(
            || Vec::with_capacity(64),
            |stack, pts| median_winding(tree, pts, stack),
        )
        .collect();
    let mut verdicts: Vec<Verdict> = winding.iter().map(|&w| verdict(w)).collect();
    // Air pockets too small for the grid to shape stay solid.
    let mut cells = vec![0u64; verdicts.len()];
    for (p, &r) in region_of_part.iter().enumerate() {
        cells[r as usize] += count(&mask_of(p as u32)) as u64;
    }
    for (v, &c) in verdicts.iter_mut().zip(&cells) {
        if *v == Verdict::Air && c < AIR_MIN_CELLS {
            *v = Verdict::Ambiguous;
        }
    }
    let parts: Vec<(BrickMask, u32)> = masks
        .into_iter()
        .zip(&region_of_part)
        .map(|(m, &r)| (m, r))
        .collect();
    let air: Vec<bool> = verdicts.iter().map(|&v| v == Verdict::Air).collect();
    if air.contains(&true) {
        let across = across_walls(band, &parts, &key_of, index, &air, tree);
        for (v, a) in verdicts.iter_mut().zip(across) {
            if a.is_some_and(|a| a < WALL_FROM) {
                *v = Verdict::Ambiguous;
            }
        }
    }
    Regions {
        parts,
        empty: empty_keys
            .iter()
            .enumerate()
            .map(|(i, &k)| (k, region_of_part[wall_count as usize + i]))
            .collect(),
        part_starts,
        winding,
        verdicts,
    }
}

/// Up to [`SAMPLES`] points per region: cell centres spread evenly over the region's cells in
/// part order, taken from its bricks without wall cells when it has any (they lie farther
/// from the surface).
fn sample_points(
    regions: usize,
    region_of_part: &[u32],
    wall_count: u32,
    mask_of: &dyn Fn(u32) -> BrickMask,
    key_of: &dyn Fn(u32) -> u32,
    index: &crate::grid::BrickIndex,
) -> Vec<Vec<[f64; 3]>> {
    // Per region: (cells in its empty bricks, cells in its wall parts).
    let mut cells = vec![(0u64, 0u64); regions];
    for (p, &r) in region_of_part.iter().enumerate() {
        let n = count(&mask_of(p as u32)) as u64;
        if (p as u32) < wall_count {
            cells[r as usize].1 += n;
        } else {
            cells[r as usize].0 += n;
        }
    }
    // The ranks (within the chosen kind of part) each region samples, ascending.
    let wanted: Vec<Vec<u64>> = cells
        .iter()
        .map(|&(empty, wall)| {
            let total = if empty > 0 { empty } else { wall };
            let k = (SAMPLES as u64).min(total);
            let mut ranks: Vec<u64> = (0..k).map(|i| (2 * i + 1) * total / (2 * k)).collect();
            ranks.dedup();
            ranks
        })
        .collect();
    let mut seen = vec![0u64; regions];
    let mut next = vec![0usize; regions];
    let mut points = vec![Vec::with_capacity(SAMPLES); regions];
    for (p, &r) in region_of_part.iter().enumerate() {
        let r = r as usize;
        let is_empty_part = p as u32 >= wall_count;
        if is_empty_part != (cells[r].0 > 0) || next[r] >= wanted[r].len() {
            continue;
        }
        let mask = mask_of(p as u32);
        let n = count(&mask) as u64;
        let b = index.coord(key_of(p as u32) as usize);
        while next[r] < wanted[r].len() && wanted[r][next[r]] < seen[r] + n {
            let local = nth_bit(&mask, (wanted[r][next[r]] - seen[r]) as u32);
            let (x, y, z) = (local & 7, (local >> 3) & 7, local >> 6);
            points[r].push([
                (b[0] * 8 + x) as f64 + 0.5,
                (b[1] * 8 + y) as f64 + 0.5,
                (b[2] * 8 + z) as f64 + 0.5,
            ]);
            next[r] += 1;
        }
        seen[r] += n;
    }
    points
}

/// What [`decide_sealed`] found.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SealedCounts {
    /// Groups of sealed vertices (joined through grid edges no triangle crosses).
    pub groups: u64,
    /// Groups whose winding number was ambiguous (left outside).
    pub ambiguous: u64,
    /// Groups inside two closed surfaces or more (|w| ≥ [`OVERLAP_FROM`]) and joined to no
    /// thin part: where closed parts overlap, left outside.
    pub overlaps: u64,
    /// Thin closed parts kept at their thickness: sealed vertices found inside, joined with
    /// their 26 neighbours.
    pub thin_parts: u64,
    /// Thin closed parts left to the thin shell because the grid cannot hold them: somewhere
    /// a grid edge crosses them with both ends outside, or none of their vertices lies
    /// [`THIN_PART_DEPTH`] deep.
    pub shelled_parts: u64,
    /// Sealed vertices joined through their 26 neighbours of which none lies
    /// [`THIN_PART_DEPTH`] deep: left to the thin shell without asking the winding number
    /// (whatever it says, such a part would be shelled), so not counted in `thin_parts` or
    /// `shelled_parts`.
    pub shallow: u64,
}

/// Decides the vertices that are still `Unknown` after [`crate::stages::sign::vertex_sides`]: those
/// sealed in by triangles on every side, with no surface-free cell to take a side from — the
/// inside of a closed part thinner than about two cells, or a pocket between sheets. They are
/// grouped through grid edges no triangle crosses (a group has one side), and each group is
/// inside if the winding number at its [`SAMPLES`] vertices farthest from the surface (median)
/// says solid; otherwise outside, as the grid alone would have it (air or ambiguous). A group
/// inside two closed surfaces or more ([`OVERLAP_FROM`]) is where closed parts overlap, not a
/// thin part: outside too, unless joined to a thin part ([`without_lone_overlaps`]).
///
/// A part found inside keeps its own surface (φ = ±UDF) only where the grid can hold it: a
/// part thinner than a cell has places no grid vertex falls into, where a grid edge crosses
/// it with both ends outside, and the exact field would leave a hole there. So the found
/// vertices are joined into parts (26 neighbours), and a part with such an edge next to one of
/// its vertices goes back to outside: it becomes a thin shell, as without the test. A part at
/// least a cell thick has a vertex in every grid edge's span across it, so it keeps its
/// surface.
pub fn decide_sealed(
    band: &Band,
    vox: &Voxelization,
    side: &mut [Side],
    tree: &LazyWindingTree,
    n: u32,
) -> SealedCounts {
    let unknown: Vec<u32> = (0..side.len() as u32)
        .into_par_iter()
        .filter(|&i| side[i as usize] == Side::Unknown)
        .collect();
    if unknown.is_empty() {
        return SealedCounts::default();
    }
    // Per band vertex, its position in `unknown` (or NOT_SEALED): O(1) look-ups below.
    let mut position = vec![NOT_SEALED; side.len()];
    for (q, &id) in unknown.iter().enumerate() {
        position[id as usize] = q as u32;
    }
    let coords = band.verts.coords_of(&unknown);
    let (group_of, members, starts) = sealed_groups(band, vox, &position, &coords);
    let groups = starts.len() - 1;
    // The sealed vertices joined through their 26 neighbours: every thin part found below is
    // within one of these, so where none of its vertices lies THIN_PART_DEPTH deep, each
    // part in it would go back to the shell (below) whatever the winding number says, and
    // its groups are not asked (on the dev corpus most sealed groups are such rims, and
    // their queries, next to the surface, were most of the inside test's time on some).
    let (reach_of, reaches) = thin_parts(band, &position, &coords, &vec![true; coords.len()]);
    let reach_depth = deepest_per_label(band, &unknown, &reach_of, reaches, |_| true);
    let shallow = |g: usize| {
        let first = members[starts[g] as usize];
        reach_depth[reach_of[first as usize] as usize] < THIN_PART_DEPTH
    };
    let asked: Vec<usize> = (0..groups).filter(|&g| !shallow(g)).collect();
    let mut verdicts = vec![Verdict::Ambiguous; groups];
    let mut overlap = vec![false; groups];
    if !asked.is_empty() {
        let tree = tree.get();
        let found: Vec<f64> = asked
            .par_iter()
            .map_init(
                || Vec::with_capacity(64),
                |stack, &g| {
                    let mut group: Vec<u32> =
                        members[starts[g] as usize..starts[g + 1] as usize].to_vec();
                    // Farthest from the surface first; ties by vertex number.
                    let udf = |q: u32| band.nearest[unknown[q as usize] as usize].udf;
                    group.sort_by(|&a, &b| udf(b).total_cmp(&udf(a)).then(a.cmp(&b)));
                    let points: Vec<[f64; 3]> = group
                        .iter()
                        .take(SAMPLES)
                        .map(|&q| coords[q as usize].map(|v| v as f64))
                        .collect();
                    median_winding(tree, &points, stack)
                },
            )
            .collect();
        for (&g, w) in asked.iter().zip(found) {
            verdicts[g] = verdict(w);
            overlap[g] = w >= OVERLAP_FROM;
        }
    }
    let solid: Vec<bool> = group_of
        .iter()
        .map(|&g| verdicts[g as usize] == Verdict::Solid)
        .collect();
    let found = without_lone_overlaps(band, &position, &coords, &solid, |q| {
        overlap[group_of[q] as usize]
    });
    // Where every deep enough set was found inside whole (the common case), its parts are
    // those sets: no second pass over the neighbours.
    let whole = (0..coords.len())
        .all(|q| found[q] == (reach_depth[reach_of[q] as usize] >= THIN_PART_DEPTH));
    let (part_of, parts) = if whole {
        renumbered(&reach_of, reaches, &found)
    } else {
        thin_parts(band, &position, &coords, &found)
    };
    let sealed = Sealed {
        position: &position,
        coords: &coords,
        found: &found,
        part_of: &part_of,
    };
    let mut too_thin = parts_with_gaps(band, vox, side, &sealed, parts, n);
    // A part whose found vertices all lie within THIN_PART_DEPTH of the surface is held by
    // the grid in too few places: a shell.
    let deepest = deepest_per_label(band, &unknown, &part_of, parts, |q| found[q]);
    for (t, &d) in too_thin.iter_mut().zip(&deepest) {
        *t |= d < THIN_PART_DEPTH;
    }
    for (q, &id) in unknown.iter().enumerate() {
        side[id as usize] = if found[q] && !too_thin[part_of[q] as usize] {
            Side::Inside
        } else {
            Side::Outside
        };
    }
    let shelled = too_thin.iter().filter(|&&t| t).count() as u64;
    let shallow_reaches = reach_depth.iter().filter(|&&d| d < THIN_PART_DEPTH).count() as u64;
    SealedCounts {
        groups: groups as u64,
        ambiguous: asked
            .iter()
            .filter(|&&g| verdicts[g] == Verdict::Ambiguous)
            .count() as u64,
        overlaps: (0..groups)
            .filter(|&g| overlap[g] && !found[members[starts[g] as usize] as usize])
            .count() as u64,
        shallow: shallow_reaches,
        thin_parts: parts as u64 - shelled,
        shelled_parts: shelled,
    }
}

/// Per label (of `count`), the largest distance to the surface of the sealed vertices
/// (`unknown`, band vertex numbers) with that label for which `counted` holds; 0 for a label
/// without any.
fn deepest_per_label(
    band: &Band,
    unknown: &[u32],
    label: &[u32],
    count: usize,
    counted: impl Fn(usize) -> bool,
) -> Vec<f32> {
    let mut deepest = vec![0f32; count];
    for (q, &id) in unknown.iter().enumerate() {
        if counted(q) {
            let l = label[q] as usize;
            deepest[l] = deepest[l].max(band.nearest[id as usize].udf);
        }
    }
    deepest
}

/// Depth, in voxels, that at least one found vertex of a thin closed part must lie below its
/// surface for the part to keep that surface: a part whose vertices are all shallower (at
/// most about 0.6 voxel thick where the grid sees it) is held by the grid in too few places,
/// and its exact field loses the rest (tapering rims, curved walls), which cost F1 on the dev
/// corpus at 256³ against the thin shell (`yogurtBottle.obj` 99.7 → 98.6, `park-trashcan.obj`
/// 65.6 → 65.2, `left_finger.STL` 95.8 → 95.1). Plates of 1.2 voxels and more have vertices
/// about 0.6 deep and keep their surface (tests/convert_enclosed.rs).
pub const THIN_PART_DEPTH: f32 = 0.3;

/// |w| at or above which a sealed group is inside two closed surfaces or more: halfway
/// between one surface and two, as [`NESTED_STEP`] is half a surface's step.
///
/// Such a group is where closed parts overlap by less than the grid resolves (a screw in a
/// hole narrower than its shaft), not a thin part of its own. Inside, it would leave both
/// parts' surfaces with inside on each side, as sheets inside the solid, and each would
/// become a thin cavity 0.9 voxel off its place (§5 of docs/ALGORITHM.md); outside, as the
/// grid alone has it, the sliver is a thin gap whose walls are the parts' exact surfaces.
/// Overlap regions the flood encloses keep the parts' surfaces too (the nested rule).
pub const OVERLAP_FROM: f64 = 1.5;

/// Marker of a band vertex that is not sealed, in [`decide_sealed`]'s position list.
const NOT_SEALED: u32 = u32::MAX;

/// Union–find over `len` items joined by `pairs`; each item's component, numbered in the
/// order of the components' smallest items, and the number of components. The same result
/// whatever the order of `pairs`.
fn components(len: usize, pairs: &[(u32, u32)], keep: impl Fn(usize) -> bool) -> (Vec<u32>, usize) {
    let mut sets = Sets((0..len as u32).collect());
    for &(a, b) in pairs {
        sets.union(a, b);
    }
    let mut label = vec![u32::MAX; len];
    let mut count = 0u32;
    for q in 0..len {
        if !keep(q) {
            continue;
        }
        let root = sets.find(q as u32) as usize;
        if root == q {
            label[q] = count;
            count += 1;
        } else {
            label[q] = label[root];
        }
    }
    (label, count as usize)
}

/// Groups of the sealed vertices (positions in `unknown`, `position` per band vertex) through
/// grid edges no triangle crosses: each position's group (numbered by smallest position), and
/// the groups' members as CSR (members, starts). The neighbour look-ups run in parallel.
fn sealed_groups(
    band: &Band,
    vox: &Voxelization,
    position: &[u32],
    coords: &[[u32; 3]],
) -> (Vec<u32>, Vec<u32>, Vec<u32>) {
    let pairs: Vec<(u32, u32)> = (0..coords.len())
        .into_par_iter()
        .flat_map_iter(|q| {
            open_neighbours(band, vox, coords[q]).filter_map(move |(j, _)| {
                let r = position[j as usize];
                (r != NOT_SEALED && r != q as u32).then_some((q as u32, r))
            })
        })
        .collect();
    let (group_of, groups) = components(coords.len(), &pairs, |_| true);
    let mut starts = vec![0u32; groups + 1];
    for &g in &group_of {
        starts[g as usize + 1] += 1;
    }
    for g in 0..groups {
        starts[g + 1] += starts[g];
    }
    let mut fill = starts.clone();
    let mut members = vec![0u32; coords.len()];
    for (q, &g) in group_of.iter().enumerate() {
        members[fill[g as usize] as usize] = q as u32;
        fill[g as usize] += 1;
    }
    (group_of, members, starts)
}

/// The 26 neighbour offsets that come after (0, 0, 0) in (x, y, z) order: each neighbouring
/// pair is visited once.
fn forward_neighbours() -> impl Iterator<Item = [i64; 3]> {
    (0..27i64)
        .map(|d| [d % 3 - 1, (d / 3) % 3 - 1, d / 9 - 1])
        .filter(|off| *off > [0, 0, 0])
}

/// Connected components, through the 26 neighbours, of the `found` sealed vertices: each
/// found position's part (numbered by smallest position), and the number of parts.
fn thin_parts(
    band: &Band,
    position: &[u32],
    coords: &[[u32; 3]],
    found: &[bool],
) -> (Vec<u32>, usize) {
    let pairs: Vec<(u32, u32)> = (0..coords.len())
        .into_par_iter()
        .filter(|&q| found[q])
        .flat_map_iter(|q| {
            let c = coords[q].map(|v| v as i64);
            forward_neighbours().filter_map(move |off| {
                let j = band
                    .verts
                    .id([c[0] + off[0], c[1] + off[1], c[2] + off[2]])?;
                let r = position[j as usize];
                (r != NOT_SEALED && found[r as usize]).then_some((q as u32, r))
            })
        })
        .collect();
    components(coords.len(), &pairs, |q| found[q])
}

/// The `solid` sealed vertices less those of overlaps ([`OVERLAP_FROM`]) that are not joined,
/// through their 26 neighbours, to a solid vertex that is no overlap.
///
/// A group inside two closed surfaces or more is where closed parts overlap (or one lies
/// inside another), not a thin part of its own: outside, as the grid alone has it — unless it
/// is joined to a thin part found inside (thin parts that cross or lap over each other, the
/// boards of a hut): there the sliver is the thin part's own inside as the grid sees it, and
/// outside it would cut the part through (the gap check would then shell all of it).
fn without_lone_overlaps(
    band: &Band,
    position: &[u32],
    coords: &[[u32; 3]],
    solid: &[bool],
    overlap: impl Fn(usize) -> bool,
) -> Vec<bool> {
    if !(0..coords.len()).any(|q| solid[q] && overlap(q)) {
        return solid.to_vec();
    }
    let (part_of, parts) = thin_parts(band, position, coords, solid);
    let mut thin = vec![false; parts];
    for q in 0..coords.len() {
        if solid[q] && !overlap(q) {
            thin[part_of[q] as usize] = true;
        }
    }
    (0..coords.len())
        .map(|q| solid[q] && (!overlap(q) || thin[part_of[q] as usize]))
        .collect()
}

/// `label` (of `count` labels) kept where `keep` holds, numbered again in the order of
/// their first kept item (as [`components`] numbers them); `u32::MAX` elsewhere.
fn renumbered(label: &[u32], count: usize, keep: &[bool]) -> (Vec<u32>, usize) {
    let mut new = vec![u32::MAX; count];
    let mut next = 0u32;
    let out = label
        .iter()
        .zip(keep)
        .map(|(&l, &k)| {
            if !k {
                return u32::MAX;
            }
            if new[l as usize] == u32::MAX {
                new[l as usize] = next;
                next += 1;
            }
            new[l as usize]
        })
        .collect();
    (out, next as usize)
}

/// The sealed vertices as [`decide_sealed`] found them: per band vertex its position among
/// them ([`NOT_SEALED`] if none), and per position its coordinates, whether the winding
/// number found it inside, and its thin part.
struct Sealed<'a> {
    position: &'a [u32],
    coords: &'a [[u32; 3]],
    found: &'a [bool],
    part_of: &'a [u32],
}

/// Whether the grid edge from `v` to `u`, both outside and crossed by the surface, passes
/// through something thinner than the edge — its ends see their closest surface points on
/// opposite sides (directions more than 120° apart) — rather than clipping a corner or a rim
/// (directions about 90° apart or less). An end closer than 10⁻³ voxel to the surface has no
/// reliable direction and does not count.
fn crosses_a_sheet(band: &Band, v: [i64; 3], u: [i64; 3]) -> bool {
    let away = |c: [i64; 3]| -> Option<[f64; 3]> {
        let near = band.nearest[band.verts.id(c)? as usize];
        (near.udf > 1e-3).then(|| std::array::from_fn(|a| c[a] as f64 - near.point[a] as f64))
    };
    match (away(v), away(u)) {
        (Some(a), Some(b)) => {
            let (la, lb) = (crate::vec3::dot(a, a).sqrt(), crate::vec3::dot(b, b).sqrt());
            crate::vec3::dot(a, b) < -0.5 * la * lb
        }
        _ => false,
    }
}

/// Which thin parts a grid edge crosses through something thinner than itself with both ends
/// outside ([`crosses_a_sheet`]) next to one of their vertices (`side` holds every other
/// vertex's side; the sealed ones are still `Unknown`).
fn parts_with_gaps(
    band: &Band,
    vox: &Voxelization,
    side: &[Side],
    sealed: &Sealed,
    parts: usize,
    n: u32,
) -> Vec<bool> {
    let Sealed {
        position,
        coords,
        found,
        part_of,
    } = *sealed;
    let mut too_thin = vec![false; parts];
    if parts == 0 {
        return too_thin;
    }
    // The found vertices and their 26 neighbours, to test edges against cheaply.
    let index = crate::grid::BrickIndex::for_resolution(n);
    let mut packed: Vec<u64> = coords
        .iter()
        .zip(found)
        .filter(|(_, &f)| f)
        .map(|(&c, _)| crate::grid::pack(&index, c))
        .collect();
    packed.sort_unstable();
    let near = dilate(&BrickSet::from_sorted_packed(n, &packed), n, Dilation::Box);
    let outside = |c: [i64; 3]| -> bool {
        band.verts.id(c).is_some_and(|i| match side[i as usize] {
            Side::Outside => true,
            Side::Unknown => !found[position[i as usize] as usize],
            Side::Inside => false,
        })
    };
    // The crossed edges with an end in `near`, found from `near`'s side (it is far smaller
    // than the crossed edges of the whole surface), brick by brick in parallel.
    let marks: Vec<u32> = (0..near.keys.len())
        .into_par_iter()
        .flat_map_iter(|s| {
            let mut out = Vec::new();
            near.for_each_member(s, |w| {
                for axis in 0..3 {
                    for lower in [true, false] {
                        let (mut v, mut u) = (w, w);
                        if lower {
                            u[axis] += 1;
                        } else {
                            v[axis] -= 1;
                        }
                        // An edge with both ends in `near` is seen from its lower end only.
                        if !lower && near.contains(v) {
                            continue;
                        }
                        if !vox.blocked[axis].contains(v) || !outside(v) || !outside(u) {
                            continue;
                        }
                        if !crosses_a_sheet(band, v, u) {
                            continue;
                        }
                        for end in [v, u] {
                            for off in cube_offsets(1) {
                                let c: [i64; 3] = std::array::from_fn(|a| end[a] + off[a]);
                                let Some(j) = band.verts.id(c) else {
                                    continue;
                                };
                                let q = position[j as usize];
                                if q != NOT_SEALED && found[q as usize] {
                                    out.push(part_of[q as usize]);
                                }
                            }
                        }
                    }
                }
            });
            out
        })
        .collect();
    for p in marks {
        too_thin[p as usize] = true;
    }
    too_thin
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn verdicts_follow_the_thresholds() {
        assert_eq!(verdict(0.02), Verdict::Air);
        assert_eq!(verdict(-0.98), Verdict::Solid);
        assert_eq!(verdict(2.0), Verdict::Solid);
        assert_eq!(verdict(0.5), Verdict::Ambiguous);
        assert_eq!(verdict(AIR_UP_TO), Verdict::Air);
        assert_eq!(verdict(SOLID_FROM), Verdict::Solid);
    }

    #[test]
    fn whole_components_renumbered_match_components_of_the_kept_items() {
        // Items 0..8 in components {0, 3, 5}, {1, 4}, {2, 7}, {6}; keep {1, 4} and {6}.
        let pairs = [(3, 0), (5, 3), (4, 1), (7, 2)];
        let (label, count) = components(8, &pairs, |_| true);
        assert_eq!(count, 4);
        let keep: Vec<bool> = (0..8).map(|q| [1, 4, 6].contains(&q)).collect();
        let direct = components(8, &pairs, |q| keep[q]);
        assert_eq!(renumbered(&label, count, &keep), direct);
        assert_eq!(direct.1, 2);
    }

    #[test]
    fn nth_bit_walks_words() {
        let mut m = [0u64; 8];
        m[0] = 0b1010;
        m[2] = 1 << 7;
        assert_eq!(nth_bit(&m, 0), 1);
        assert_eq!(nth_bit(&m, 1), 3);
        assert_eq!(nth_bit(&m, 2), 128 + 7);
    }
}
