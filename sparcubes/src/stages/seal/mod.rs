//! Stage 4: openings small for their part are sealed, so a nearly closed solid stays solid
//! (docs/ALGORITHM.md §4; `Params::seal_openings`, with the inside test).
//!
//! The exact flood (§3) enters a closed part through any hole wider than about a cell, and
//! the part then becomes a thin shell as a whole — at finer grids for smaller holes. This
//! stage repeats the flood on a coarse grid of fixed size in the object's own units
//! ([`Scale`]), with the walls grown by a few coarse cells: the grown walls close every
//! opening narrower than about 1/16 of the grid, and what that flood does not reach but the
//! exact flood did is a *sealed pocket*. A pocket whose source winding number reads solid
//! (the enclosed regions' rule, §6) is taken back from the outside; others stay outside (a
//! cavity behind a slot, the inside of a cup). The grown walls are then given back: their
//! coarse cells go to the pocket or the outside, whichever is nearer through free cells
//! ([`decide::compete`]), and so, cell by cell, do the fine cells of the coarse cells that hold
//! surface next to the pocket ([`fine::compete_fine`]). Inside walls the pocket and the
//! outside keep their own side; in an opening they meet about halfway, and the cells there
//! ([`apply::cap_cells`]) join the ring (§9), where the cap across the opening is extracted.
//!
//! - [`coarse`] — the dense bit grid at the sealing scale.
//! - [`decide`] — pockets, their winding vote, the coarse competition.
//! - [`fine`] — the fine competition in coarse cells with surface.
//! - [`apply`] — the result written into the flood; the cap cells.

pub mod apply;
pub mod coarse;
pub mod decide;
pub mod fine;

use crate::grid::BrickMask;
use crate::queries::winding::LazyWindingTree;
use crate::stages::flood::{flood_outside, CellSide, Flood};
use crate::stages::voxelize::Voxelization;
use coarse::{downsample, CoarseGrid, Run};

/// Coarse cells per axis at most: the sealing's grid, the same share of the object at every
/// resolution from 256 up.
pub const COARSE_CELLS: u32 = 128;

/// The sealing's scale at one resolution: coarse cells of `cell` fine cells (a power of two,
/// `N / 128` or just below), `side` of them per axis, and the walls grown by `radius` coarse
/// cells, about `N / 32` voxels. An opening is sealed where every point of it lies within
/// `radius` coarse cells of its rim: openings up to `(2·radius + 1)·cell − 1` voxels across
/// always are (17 at 256³, 35 at 512³, 71 at 1024³: 6.6–6.9 % of the grid), from about
/// `(2·radius + 2)·cell` never (7.8 %); a part must be thicker than about
/// `(2·radius + 3)·cell` voxels (8.6 % of the grid) to hold a pocket at all.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Scale {
    /// Fine cells per coarse cell along each axis.
    pub cell: u32,
    /// Coarse cells per axis.
    pub side: usize,
    /// Coarse cells the walls grow by.
    pub radius: usize,
}

impl Scale {
    /// The scale at resolution `n`.
    pub fn for_resolution(n: u32) -> Self {
        let wanted = (n / COARSE_CELLS).max(1);
        let cell = 1u32 << (31 - wanted.leading_zeros());
        let radius = ((n as f64 / (32.0 * cell as f64)).round() as usize).max(1);
        Self {
            cell,
            side: n.div_ceil(cell) as usize,
            radius,
        }
    }
}

/// What [`seal_openings`] did.
#[derive(Debug, Clone, Default)]
pub struct Sealing {
    /// A fine cell of each solid pocket taken back from the outside: the enclosed regions'
    /// classification (§6) checks the region each lies in, and unseals it unless solid.
    pub seeds: Vec<[i64; 3]>,
    /// The fine cells the caps across the openings run through, per brick key (ascending):
    /// candidate cells for the ring (§9).
    pub caps: Vec<(u32, BrickMask)>,
}

/// Seals the openings of nearly closed solids (see the module docs): the solid pockets'
/// cells are taken out of `flood`'s outside (an empty brick split by a cap becomes a wall
/// brick of `vox.walls` with no wall cell), and the cap cells are returned. Nothing changes
/// where no solid pocket is kept.
pub fn seal_openings(
    vox: &mut Voxelization,
    flood: &mut Flood,
    tree: &LazyWindingTree,
    n: u32,
) -> Sealing {
    let scale = Scale::for_resolution(n);
    let walls = downsample(&vox.walls, scale.cell, scale.side);
    let grown = walls.dilate(scale.radius);
    let pockets = find_pockets(vox, flood, &grown, scale);
    let mut sealing = Sealing::default();
    if pockets.is_empty() {
        return sealing;
    }
    let tree = tree.get();
    let solid: Vec<Vec<Run>> = pockets
        .into_iter()
        .filter(|runs| decide::is_solid(decide::component_winding(tree, runs, scale.cell)))
        .collect();
    if solid.is_empty() {
        return sealing;
    }
    // The grown walls given back: their surface-free coarse cells, contested by the solid
    // pockets and by every other surface-free cell. (Surface-free coarse cells the exact flood
    // did not reach never share a face with ones it did, so neither side's growth enters them.)
    let free = walls.complement();
    let band = free.and(&grown);
    let others = free
        .and_not(&band)
        .and_not(&CoarseGrid::of_runs(scale.side, solid.iter().flatten()));
    let (inside, outside, kept) = decide::give_back(&solid, &others, &band, &walls);
    // One fine cell of each pocket kept, for the enclosed regions' check (§6).
    sealing.seeds = solid
        .iter()
        .zip(&kept)
        .filter(|(_, &k)| k)
        .map(|(runs, _)| [runs[0].x0, runs[0].y, runs[0].z].map(|v| (v as u32 * scale.cell) as i64))
        .collect();
    if !sealing.seeds.is_empty() {
        let holding = walls.or(&band.and_not(&inside).and_not(&outside));
        sealing.caps = seal_fine(vox, flood, &inside, &holding, scale, n);
    }
    sealing
}

/// The sets of coarse cells that the flood over the grown walls does not reach but the exact
/// flood did: one lookup each, since the fine cells of a connected set of surface-free coarse
/// cells are all joined.
fn find_pockets(
    vox: &Voxelization,
    flood: &Flood,
    grown: &CoarseGrid,
    scale: Scale,
) -> Vec<Vec<Run>> {
    let grown_bricks = grown.to_bricks();
    let reached = CoarseGrid::from_flood(scale.side, &grown_bricks, &flood_outside(&grown_bricks));
    let unreached = grown.or(&reached).complement();
    if unreached.is_empty() {
        return Vec::new();
    }
    decide::components(&unreached)
        .into_iter()
        .filter(|runs| {
            let r = &runs[0];
            let first = [r.x0, r.y, r.z].map(|v| (v as u32 * scale.cell) as i64);
            flood.cell(&vox.walls, first) == CellSide::Outside
        })
        .collect()
}

/// The fine part of the sealing: the competition in the coarse cells with surface (or left to
/// neither side) joined to the sealed region `inside`, the sealed cells taken out of the
/// flood, and the cap cells, searched where the region meets anything but itself.
fn seal_fine(
    vox: &mut Voxelization,
    flood: &mut Flood,
    inside: &CoarseGrid,
    holding: &CoarseGrid,
    scale: Scale,
    n: u32,
) -> Vec<(u32, BrickMask)> {
    let contested = decide::near_inside(holding, inside);
    let won = fine::compete_fine(&vox.walls, flood, inside, &contested, scale.cell);
    let sealed = apply::sealed_cells(&vox.walls, flood, inside, won, scale.cell);
    apply::apply(vox, flood, &sealed, n);
    let meeting = inside.and(&inside.complement().dilate(1)).or(&contested);
    let near = fine::bricks_of(&meeting, &vox.walls.index, scale.cell);
    apply::cap_cells(&vox.walls, flood, &sealed, &near)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scale_is_the_same_share_of_the_grid_at_every_resolution() {
        let s = |n| Scale::for_resolution(n);
        assert_eq!(
            s(256),
            Scale {
                cell: 2,
                side: 128,
                radius: 4
            }
        );
        assert_eq!(
            s(512),
            Scale {
                cell: 4,
                side: 128,
                radius: 4
            }
        );
        assert_eq!(
            s(1024),
            Scale {
                cell: 8,
                side: 128,
                radius: 4
            }
        );
        assert_eq!(
            s(300),
            Scale {
                cell: 2,
                side: 150,
                radius: 5
            }
        );
        assert_eq!(
            s(64),
            Scale {
                cell: 1,
                side: 64,
                radius: 2
            }
        );
        // At most 256 coarse cells a side (rows of at most four words, `decide::compete`).
        assert!((8..=4096).all(|n| s(n).side <= 256));
        for n in [256, 300, 512, 1000, 1024, 2048, 4096] {
            let sc = s(n);
            let sure = ((2 * sc.radius + 1) as u32 * sc.cell - 1) as f64 / n as f64;
            assert!((0.06..0.075).contains(&sure), "{n}: {sure}");
        }
    }
}
