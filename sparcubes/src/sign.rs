//! Stage 5: the sign of every band vertex, and the thin-shell treatment of open parts.
//!
//! * A vertex touching an outside cell is outside (that cell is free of surface and joined to
//!   the border); one touching only inside cells is inside. A vertex whose eight cells are all
//!   wall cells takes its side from labelled neighbours through grid edges no triangle crosses
//!   (synchronous rounds; a vertex that sees both sides sides with inside, which keeps sealed
//!   holes sealed).
//! * Every crossed grid edge is evidence about the surface it crosses: ends on different sides
//!   → a closed part; ends on the same side → an open sheet (or a part thinner than a voxel,
//!   or a sheet inside a closed part). Evidence is summed over the 3×3×3 cells around each
//!   vertex's closest surface point; where "same side" wins, the vertex belongs to a thin shell:
//!   φ = UDF − t outside (φ = t − UDF inside, a thin cavity), so the zero level set is a closed
//!   shell 2t thick around the sheet. Elsewhere φ = ±UDF, whose zero level set is the surface
//!   itself: closed parts are not dilated.

use crate::band::Band;
use crate::flood::{CellSide, Flood};
use crate::grid::{for_each_bit, BrickSet, Numbered};
use crate::voxelize::Voxelization;
use rayon::prelude::*;

/// Side of a vertex.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Side {
    /// Not decided yet.
    Unknown = 0,
    /// Outside every closed part.
    Outside = 1,
    /// Inside a closed part.
    Inside = 2,
}

/// Per-vertex sign information (parallel to the band's vertices).
#[derive(Debug, Clone)]
pub struct Signs {
    /// Side of each vertex.
    pub side: Vec<Side>,
    /// Whether the vertex belongs to a thin shell around an open part.
    pub thin: Vec<bool>,
}

const STEPS: [[i64; 3]; 3] = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];

fn brick_coords(set: &BrickSet, s: usize) -> Vec<[i64; 3]> {
    let b = set.index.coord(set.keys[s] as usize);
    let mut out = Vec::new();
    for_each_bit(&set.masks[s], |x, y, z| {
        out.push([
            (b[0] * 8 + x) as i64,
            (b[1] * 8 + y) as i64,
            (b[2] * 8 + z) as i64,
        ])
    });
    out
}

/// Side of each vertex from the cells it touches; `Unknown` where all eight are wall cells.
fn sides_from_cells(band: &Band, walls: &BrickSet, flood: &Flood) -> Vec<Side> {
    let set = &band.verts.set;
    let per_brick: Vec<Vec<Side>> = (0..set.keys.len())
        .into_par_iter()
        .map(|s| {
            brick_coords(set, s)
                .into_iter()
                .map(|v| {
                    let mut inside = false;
                    for d in 0..8i64 {
                        let c = [v[0] - (d & 1), v[1] - ((d >> 1) & 1), v[2] - (d >> 2)];
                        match flood.cell(walls, c) {
                            CellSide::Outside => return Side::Outside,
                            CellSide::Inside => inside = true,
                            CellSide::Wall => {}
                        }
                    }
                    if inside {
                        Side::Inside
                    } else {
                        Side::Unknown
                    }
                })
                .collect()
        })
        .collect();
    per_brick.into_iter().flatten().collect()
}

/// Whether the grid edge between `v` and `v + e_axis` is crossed by the surface.
#[inline]
fn blocked(vox: &Voxelization, v: [i64; 3], axis: usize) -> bool {
    vox.blocked[axis].contains(v)
}

/// Resolves `Unknown` vertices through unblocked edges, in synchronous rounds so the result
/// does not depend on order; what stays unknown (fully enclosed by triangles) is outside.
fn resolve_enclosed(band: &Band, vox: &Voxelization, side: &mut [Side]) {
    let coords = band.verts.coords();
    let mut pending: Vec<usize> = (0..side.len())
        .filter(|&i| side[i] == Side::Unknown)
        .collect();
    while !pending.is_empty() {
        let decided: Vec<(usize, Side)> = pending
            .par_iter()
            .filter_map(|&i| {
                let c = coords[i];
                let v = [c[0] as i64, c[1] as i64, c[2] as i64];
                let mut seen_out = false;
                for (axis, step) in STEPS.iter().enumerate() {
                    for dir in [-1i64, 1] {
                        let u = [
                            v[0] + dir * step[0],
                            v[1] + dir * step[1],
                            v[2] + dir * step[2],
                        ];
                        let lower = if dir > 0 { v } else { u };
                        if blocked(vox, lower, axis) {
                            continue;
                        }
                        match band.verts.id(u).map(|j| side[j as usize]) {
                            Some(Side::Inside) => return Some((i, Side::Inside)),
                            Some(Side::Outside) => seen_out = true,
                            _ => {}
                        }
                    }
                }
                seen_out.then_some((i, Side::Outside))
            })
            .collect();
        if decided.is_empty() {
            break;
        }
        for &(i, s) in &decided {
            side[i] = s;
        }
        pending.retain(|&i| side[i] == Side::Unknown);
    }
    for s in side.iter_mut() {
        if *s == Side::Unknown {
            *s = Side::Outside;
        }
    }
}

/// Evidence per wall cell: +1 for each crossed edge of the cell whose ends are on the same
/// side, −1 for each whose ends differ.
fn edge_evidence(band: &Band, vox: &Voxelization, walls: &Numbered, side: &[Side]) -> Vec<i32> {
    let mut evidence = vec![0i32; walls.len];
    for (axis, set) in vox.blocked.iter().enumerate() {
        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
        for s in 0..set.keys.len() {
            for v in brick_coords(set, s) {
                let mut u = v;
                u[axis] += 1;
                let (Some(i), Some(j)) = (band.verts.id(v), band.verts.id(u)) else {
                    continue;
                };
                let vote = if side[i as usize] == side[j as usize] {
                    1
                } else {
                    -1
                };
                for d in 0..4i64 {
                    let mut cell = v;
                    cell[b] -= d & 1;
                    cell[c] -= d >> 1;
                    if let Some(k) = walls.id(cell) {
                        evidence[k as usize] += vote;
                    }
                }
            }
        }
    }
    evidence
}

/// Sum of evidence over the 3×3×3 cells around each wall cell; computed only near cells with
/// positive evidence (elsewhere the sum cannot be positive and is left at 0).
fn smoothed_evidence(walls: &Numbered, evidence: &[i32]) -> Vec<i32> {
    let set = &walls.set;
    let positive: Vec<bool> = (0..set.keys.len())
        .map(|s| {
            let start = walls.offsets[s] as usize;
            let len = crate::grid::count(&set.masks[s]) as usize;
            evidence[start..start + len].iter().any(|&e| e > 0)
        })
        .collect();
    let per_brick: Vec<Vec<i32>> = (0..set.keys.len())
        .into_par_iter()
        .map(|s| {
            let b = set.index.coord(set.keys[s] as usize);
            let near_positive = (0..27).any(|d| {
                let nb = [
                    b[0] as i64 + d % 3 - 1,
                    b[1] as i64 + (d / 3) % 3 - 1,
                    b[2] as i64 + d / 9 - 1,
                ];
                set.index.slot(nb).is_some_and(|t| positive[t])
            });
            let cells = brick_coords(set, s);
            if !near_positive {
                return vec![0; cells.len()];
            }
            cells
                .iter()
                .map(|c| {
                    let mut sum = 0;
                    for d in 0..27i64 {
                        let q = [c[0] + d % 3 - 1, c[1] + (d / 3) % 3 - 1, c[2] + d / 9 - 1];
                        if let Some(k) = walls.id(q) {
                            sum += evidence[k as usize];
                        }
                    }
                    sum
                })
                .collect()
        })
        .collect();
    per_brick.into_iter().flatten().collect()
}

/// Decides the side of every band vertex and which vertices belong to thin shells.
pub fn compute_signs(band: &Band, vox: &Voxelization, flood: &Flood) -> Signs {
    let mut side = sides_from_cells(band, &vox.walls, flood);
    resolve_enclosed(band, vox, &mut side);
    let walls = Numbered::new(vox.walls.clone());
    let evidence = edge_evidence(band, vox, &walls, &side);
    let smooth = smoothed_evidence(&walls, &evidence);
    let thin = band
        .closest
        .par_iter()
        .map(|p| {
            // The cell holding the closest point touches the surface; a point on a cell
            // face (or rounded to f32 next to one) may name either neighbour, so try both.
            let cell = (0..8).find_map(|d| {
                let c: [i64; 3] = std::array::from_fn(|a| {
                    let e = if (d >> a) & 1 == 0 { -1e-3 } else { 1e-3 };
                    (p[a] + e).floor() as i64
                });
                walls.id(c)
            });
            cell.is_some_and(|k| smooth[k as usize] > 0)
        })
        .collect();
    Signs { side, thin }
}
