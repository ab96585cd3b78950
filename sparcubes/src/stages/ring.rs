//! Stage 9: the surface-free cells next to the walls that the zero level set reaches.
//!
//! The core band holds the corners of the wall cells. A cell free of surface has a sign change
//! only if one of its corners disagrees with the cell's own side: a vertex that is a corner of
//! no wall cell has eight surface-free cells around it, so it is at least one voxel from the
//! surface — farther than the shell half-thickness t < 1 — and its φ has the sign of its side,
//! which is the cell's. A corner of a wall cell can disagree where a thin shell reaches past
//! the wall cells (φ = UDF − t < 0 on an outside vertex, or t − UDF ≥ 0 in a thin cavity) or
//! where an inside cell meets an outside cell at a corner or an edge. Only those cells'
//! corners outside the core band get distances too (with [`crate::stages::band::REACH`]); around
//! closed parts the band stays the corners of the wall cells, and the kept cells are exactly
//! those of a band grown around every wall cell.

use crate::grid::{difference, dilate, for_each_bit, merge_masks, BrickMask, BrickSet, Dilation};
use crate::mesh::GridMesh;
use crate::params::Params;
use crate::stages::band::{compute_band, Band, REACH};
use crate::stages::deform::{compute_field, Field};
use crate::stages::flood::Flood;
use crate::stages::sign::{ring_signs, CoreSigns, Signs, TOUCHES_INSIDE, TOUCHES_OUTSIDE};
use rayon::prelude::*;

/// The ring: its cells, and the band of its own vertices (its cells' corners that are not in
/// the core band) with their signs and field.
pub struct Ring {
    /// The ring's cells, with the cells the caps of sealed openings run through.
    pub cells: BrickSet,
    /// Distances and closest points of the ring's own vertices.
    pub band: Band,
    /// Their sides and thin-shell flags.
    pub signs: Signs,
    /// Their φ and displacements.
    pub field: Field,
}

/// What the ring is computed from: the mesh (in grid coordinates) with its triangles'
/// planes, the core band with its signs and φ, the walls and the flood.
pub struct RingInputs<'a> {
    /// The mesh in grid coordinates.
    pub grid: &'a GridMesh,
    /// Its triangles' planes ([`crate::stages::band::triangle_planes`]).
    pub planes: &'a [[f64; 4]],
    /// The core band.
    pub core: &'a Band,
    /// The core band's signs.
    pub signs: &'a CoreSigns,
    /// The core band's φ.
    pub sdf: &'a [f32],
    /// The wall cells.
    pub walls: &'a BrickSet,
    /// The outside cells.
    pub flood: &'a Flood,
}

/// Stage 9: the ring's cells (those of [`ring_cells`] and the `caps` of sealed openings), the
/// distances of their own vertices (reach [`REACH`]), their signs and their field.
pub fn ring(inputs: &RingInputs<'_>, caps: Vec<(u32, BrickMask)>, params: &Params) -> Ring {
    let n = params.resolution;
    let RingInputs {
        grid,
        planes,
        core,
        signs,
        sdf,
        walls,
        flood,
    } = *inputs;
    let cells = with_caps(ring_cells(core, signs, sdf, walls, flood, n), caps, n);
    // The ring's own vertices: corners of ring cells that are not in the core band.
    let verts = difference(&dilate(&cells, n, Dilation::Corners), &core.verts.set, n);
    let band = compute_band(grid, planes, verts, REACH);
    let signs = ring_signs(&band, walls, flood, signs);
    let field = compute_field(&band, &signs, params);
    Ring {
        cells,
        band,
        signs,
        field,
    }
}

/// The ring's cells with the cells the caps of sealed openings run through (stage 4): surface-free
/// cells where a sealed pocket meets the outside, whose corners need φ as the ring's do.
fn with_caps(rings: BrickSet, caps: Vec<(u32, BrickMask)>, n: u32) -> BrickSet {
    if caps.is_empty() {
        return rings;
    }
    let keyed = rings.keys.into_iter().zip(rings.masks).collect();
    BrickSet::from_masks(n, merge_masks(keyed, caps))
}

/// The surface-free cells with a corner in `core` whose φ (`sdf`, parallel to the core band's
/// vertices) disagrees with the cell's side. Whole bricks at a time: the disagreeing vertices
/// (inside ones touching an outside cell, outside ones touching an inside cell) are grown to
/// the cells they are corners of, and masked with the outside (inside) cells.
pub fn ring_cells(
    core: &Band,
    signs: &CoreSigns,
    sdf: &[f32],
    walls: &BrickSet,
    flood: &Flood,
    n: u32,
) -> BrickSet {
    let verts = &core.verts;
    let disagreeing: Vec<(BrickMask, BrickMask)> = (0..verts.set.keys.len())
        .into_par_iter()
        .map(|s| {
            let (mut inside, mut outside) = ([0u64; 8], [0u64; 8]);
            let mut i = verts.offsets[s] as usize;
            for_each_bit(&verts.set.masks[s], |x, y, z| {
                let bit = 1u64 << (x + 8 * y);
                if sdf[i] < 0.0 {
                    if signs.touches[i] & TOUCHES_OUTSIDE != 0 {
                        inside[z as usize] |= bit;
                    }
                } else if signs.touches[i] & TOUCHES_INSIDE != 0 {
                    outside[z as usize] |= bit;
                }
                i += 1;
            });
            (inside, outside)
        })
        .collect();
    let keyed = |pick: fn(&(BrickMask, BrickMask)) -> BrickMask| {
        let list = verts
            .set
            .keys
            .iter()
            .zip(&disagreeing)
            .map(|(&k, d)| (k, pick(d)))
            .collect();
        BrickSet::from_masks(n, list)
    };
    // Cells of disagreeing vertices, masked with the cells of the other side. Core vertices
    // lie at least the margin inside the grid, so every such cell is a grid cell.
    let cells_of = |set: BrickSet, side: &(dyn Fn(usize) -> BrickMask + Sync)| {
        let grown = dilate(&set, n, Dilation::Cells);
        grown
            .keys
            .par_iter()
            .zip(&grown.masks)
            .map(|(&k, m)| {
                let other = side(k as usize);
                (k, std::array::from_fn(|z| m[z] & other[z]))
            })
            .collect::<Vec<(u32, BrickMask)>>()
    };
    let from_inside = cells_of(keyed(|d| d.0), &|k| flood.outside_cells(walls, k));
    let from_outside = cells_of(keyed(|d| d.1), &|k| flood.inside_cells(walls, k));
    BrickSet::from_masks(n, merge_masks(from_inside, from_outside))
}
