//! Finding the enclosed regions and deciding each solid, air or ambiguous
//! ([`classify_regions`]).

use super::regions::Regions;
use super::vote::{median_winding, verdict, Verdict, SAMPLES};
use crate::grid::{
    count, face_carry, for_each_bit, is_empty, nth_bit, BrickMask, BrickSet, NO_BRICK,
};
use crate::queries::winding::{LazyWindingTree, WindingTree};
use crate::stages::band::Band;
use crate::stages::flood::{grow_within, Flood, FULL};
use crate::union_find::SharedSets;
use rayon::prelude::*;

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
/// [`SOLID_FROM`](super::vote::SOLID_FROM), because a wall that is solid for a cell deep reads close to 1 there, and
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
/// wall ([`across_walls`]) at least [`SOLID_FROM`](super::vote::SOLID_FROM). Where it is not, the wall is thinner than a cell, or a surface modelled
/// two-sided as coincident faces of both orientations (a box of double faces: the copies
/// cancel, so |w| is 0 inside and out), and the region is ambiguous: solid, as reachability
/// says.
pub fn classify_regions(
    walls: &BrickSet,
    flood: &Flood,
    band: &Band,
    tree: &LazyWindingTree,
) -> Regions {
    let parts = Parts::new(walls, flood);
    if parts.total() == 0 {
        return Regions {
            part_starts: parts.starts,
            ..Regions::default()
        };
    }
    let (region_of_part, regions) = parts.regions();
    let mask_of = |p: u32| parts.mask_of(p);
    let key_of = |p: u32| parts.key_of(p);
    let points = sample_points(
        regions,
        &region_of_part,
        parts.wall_count(),
        &mask_of,
        &key_of,
        &walls.index,
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
    too_small_for_air(&mut verdicts, &region_of_part, &mask_of);
    let labelled: Vec<(BrickMask, u32)> = parts
        .masks
        .iter()
        .zip(&region_of_part)
        .map(|(&m, &r)| (m, r))
        .collect();
    let air: Vec<bool> = verdicts.iter().map(|&v| v == Verdict::Air).collect();
    if air.contains(&true) {
        let across = across_walls(band, &labelled, &key_of, &walls.index, &air, tree);
        for (v, a) in verdicts.iter_mut().zip(across) {
            if a.is_some_and(|a| a < WALL_FROM) {
                *v = Verdict::Ambiguous;
            }
        }
    }
    let wall_count = parts.wall_count() as usize;
    Regions {
        parts: labelled,
        empty: (parts.empty_keys.iter().enumerate())
            .map(|(i, &k)| (k, region_of_part[wall_count + i]))
            .collect(),
        part_starts: parts.starts,
        winding,
        verdicts,
    }
}

/// Air regions of fewer than [`AIR_MIN_CELLS`] cells (`region_of_part`, the cells of part `p`
/// by `mask_of`) are too small for the grid to shape: ambiguous, so solid.
fn too_small_for_air(
    verdicts: &mut [Verdict],
    region_of_part: &[u32],
    mask_of: &dyn Fn(u32) -> BrickMask,
) {
    let mut cells = vec![0u64; verdicts.len()];
    for (p, &r) in region_of_part.iter().enumerate() {
        cells[r as usize] += count(&mask_of(p as u32)) as u64;
    }
    for (v, &c) in verdicts.iter_mut().zip(&cells) {
        if *v == Verdict::Air && c < AIR_MIN_CELLS {
            *v = Verdict::Ambiguous;
        }
    }
}

/// The enclosed cells of a flood as numbered parts: first the connected parts of each wall
/// brick's enclosed cells (by brick slot, then part), then the bricks without wall cells the
/// flood does not reach (by key), each one part.
struct Parts<'a> {
    /// The wall cells.
    walls: &'a BrickSet,
    /// Per wall brick, its first part; one more entry at the end.
    starts: Vec<u32>,
    /// The wall bricks' parts.
    masks: Vec<BrickMask>,
    /// Keys of the empty bricks the flood does not reach, ascending.
    empty_keys: Vec<u32>,
}

impl<'a> Parts<'a> {
    /// The parts of the cells of `walls`' brick space that `flood` does not reach.
    fn new(walls: &'a BrickSet, flood: &Flood) -> Self {
        let index = &walls.index;
        let (starts, masks) = wall_parts(walls, flood);
        let empty_keys: Vec<u32> = (0..index.slots.len() as u32)
            .into_par_iter()
            .filter(|&k| index.slots[k as usize] == NO_BRICK && !flood.empty_outside[k as usize])
            .collect();
        Self {
            walls,
            starts,
            masks,
            empty_keys,
        }
    }

    /// Parts in wall bricks (they are numbered first).
    fn wall_count(&self) -> u32 {
        self.masks.len() as u32
    }

    /// All parts.
    fn total(&self) -> usize {
        self.masks.len() + self.empty_keys.len()
    }

    /// The cells of part `p` in its brick.
    fn mask_of(&self, p: u32) -> BrickMask {
        if p < self.wall_count() {
            self.masks[p as usize]
        } else {
            FULL
        }
    }

    /// The brick key of part `p`.
    fn key_of(&self, p: u32) -> u32 {
        let wall_count = self.wall_count();
        if p < wall_count {
            let s = self.starts.partition_point(|&st| st <= p) - 1;
            self.walls.keys[s]
        } else {
            self.empty_keys[(p - wall_count) as usize]
        }
    }

    /// The part of the empty brick with key `key`, if the flood does not reach it.
    fn part_of_empty(&self, key: u32) -> Option<u32> {
        self.empty_keys
            .binary_search(&key)
            .ok()
            .map(|i| self.wall_count() + i as u32)
    }

    /// Each part's region, numbered by its smallest part, and the number of regions: parts
    /// joined across the +x, +y, +z face of their brick (each face pair once), the parts
    /// shared out among the threads (the numbering does not depend on their order).
    fn regions(&self) -> (Vec<u32>, usize) {
        let index = &self.walls.index;
        let sets = SharedSets::new(self.total());
        (0..self.total() as u32)
            .into_par_iter()
            .with_min_len(4096)
            .for_each(|p| {
                let b = index.coord(self.key_of(p) as usize);
                let mask = self.mask_of(p);
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
                    self.join_across(&sets, p, index.key(nb) as u32, &carry);
                }
            });
        sets.into_sets().labels(|_| true)
    }

    /// Joins part `p` with the parts of the brick with key `key` that its face cells `carry`
    /// (moved into that brick) touch.
    fn join_across(&self, sets: &SharedSets, p: u32, key: u32, carry: &BrickMask) {
        match self.walls.index.slots[key as usize] {
            NO_BRICK => {
                if let Some(q) = self.part_of_empty(key) {
                    sets.union(p, q);
                }
            }
            s => {
                let s = s as usize;
                for q in self.starts[s]..self.starts[s + 1] {
                    let m = &self.masks[q as usize];
                    if (0..8).any(|z| carry[z] & m[z] != 0) {
                        sets.union(p, q);
                    }
                }
            }
        }
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
