//! Stage 6b: the surface-free cells next to the walls that the zero level set reaches.
//!
//! The core band holds the corners of the wall cells. A cell free of surface has a sign change
//! only if one of its corners disagrees with the cell's own side: a vertex that is a corner of
//! no wall cell has eight surface-free cells around it, so it is at least one voxel from the
//! surface — farther than the shell half-thickness t < 1 — and its φ has the sign of its side,
//! which is the cell's. A corner of a wall cell can disagree where a thin shell reaches past
//! the wall cells (φ = UDF − t < 0 on an outside vertex, or t − UDF ≥ 0 in a thin cavity) or
//! where an inside cell meets an outside cell at a corner or an edge. Only those cells get a
//! band of their own (with [`crate::band::REACH`]); around closed parts the band stays the
//! corners of the wall cells, and the kept cells are exactly those of a band grown around
//! every wall cell.

use crate::band::Band;
use crate::flood::{CellSide, Flood};
use crate::grid::{for_each_bit, pack, BrickSet};
use crate::sign::{Signs, TOUCHES_INSIDE, TOUCHES_OUTSIDE};
use rayon::prelude::*;

/// The surface-free cells with a corner in `core` whose φ (`sdf`, parallel to the core band's
/// vertices) disagrees with the cell's side.
pub fn ring_cells(
    core: &Band,
    signs: &Signs,
    sdf: &[f32],
    walls: &BrickSet,
    flood: &Flood,
    n: u32,
) -> BrickSet {
    let verts = &core.verts;
    let index = &walls.index;
    let mut packed: Vec<u64> = (0..verts.set.keys.len())
        .into_par_iter()
        .fold(Vec::new, |mut out: Vec<u64>, s| {
            let b = verts.set.index.coord(verts.set.keys[s] as usize);
            let mut i = verts.offsets[s] as usize;
            for_each_bit(&verts.set.masks[s], |x, y, z| {
                let inside = sdf[i] < 0.0;
                let touches = signs.touches[i];
                i += 1;
                let disagrees = if inside {
                    touches & TOUCHES_OUTSIDE != 0
                } else {
                    touches & TOUCHES_INSIDE != 0
                };
                if !disagrees {
                    return;
                }
                let v = [
                    (b[0] * 8 + x) as i64,
                    (b[1] * 8 + y) as i64,
                    (b[2] * 8 + z) as i64,
                ];
                for d in 0..8i64 {
                    let c = [v[0] - (d & 1), v[1] - ((d >> 1) & 1), v[2] - (d >> 2)];
                    if c.iter().any(|&a| a < 0 || a >= n as i64) {
                        continue;
                    }
                    let other = match flood.cell(walls, c) {
                        CellSide::Outside => inside,
                        CellSide::Inside => !inside,
                        CellSide::Wall => false,
                    };
                    if other {
                        out.push(pack(index, [c[0] as u32, c[1] as u32, c[2] as u32]));
                    }
                }
            });
            out
        })
        .reduce(Vec::new, |mut a, b| {
            a.extend(b);
            a
        });
    packed.par_sort_unstable();
    packed.dedup();
    BrickSet::from_sorted_packed(n, &packed)
}
