//! Stage 7: the sign of every band vertex, and the thin-shell treatment of open parts.
//!
//! * A vertex touching an outside cell is outside (that cell is free of surface and joined to
//!   the border); one touching only inside cells is inside. A vertex whose eight cells are all
//!   wall cells takes its side from labelled neighbours through grid edges no triangle crosses
//!   (synchronous rounds; a vertex that sees both sides sides with inside, which keeps sealed
//!   holes sealed).
//! * Every crossed grid edge is evidence about the surface it crosses: ends on different sides
//!   → a closed part; ends on the same side → an open sheet (or a part thinner than a voxel,
//!   or a sheet inside a closed part). Evidence is summed over the 3×3×3 cells around each
//!   vertex's closest surface point; unless "different sides" wins (a sum of 0, no crossed
//!   edge nearby, counts as thin), the vertex belongs to a thin shell:
//!   φ = UDF − t outside (φ = t − UDF inside, a thin cavity), so the zero level set is a closed
//!   shell 2t thick around the sheet. Elsewhere φ = ±UDF, whose zero level set is the surface
//!   itself: closed parts are not dilated.

use crate::grid::{
    cube_offsets, face_carry, for_each_bit, shift, split, test, BrickMask, BrickSet, X0, Y0,
};
use crate::stages::band::Band;
use crate::stages::flood::Flood;
use crate::stages::inside::nesting::Nesting;
use crate::stages::vertex_side::{open_neighbours, Side};
use crate::stages::voxelize::Voxelization;
use rayon::prelude::*;

/// Per-vertex sign information (parallel to a band's vertices).
#[derive(Debug, Clone)]
pub struct Signs {
    /// Side of each vertex.
    pub side: Vec<Side>,
    /// Whether the vertex belongs to a thin shell around an open part.
    pub thin: Vec<bool>,
}

/// The core band's signs and what the ring stage ([`crate::stages::ring`], [`ring_signs`]) needs
/// besides them.
#[derive(Debug, Clone)]
pub struct CoreSigns {
    /// Side and thin flag per core vertex.
    pub signs: Signs,
    /// Which kinds of surface-free cells each vertex touches ([`TOUCHES_OUTSIDE`],
    /// [`TOUCHES_INSIDE`]); 0 for a vertex whose eight cells are all wall cells.
    pub touches: Vec<u8>,
    /// Per wall brick (parallel to the walls' bricks): the wall cells that belong to a thin
    /// part.
    pub thin_cells: Vec<BrickMask>,
}

/// Bit of [`CoreSigns::touches`]: the vertex is a corner of a surface-free outside cell.
pub const TOUCHES_OUTSIDE: u8 = 1;
/// Bit of [`CoreSigns::touches`]: the vertex is a corner of a surface-free inside cell.
pub const TOUCHES_INSIDE: u8 = 2;

/// Which surface-free cells each vertex touches, as [`CoreSigns::touches`] bits.
///
/// A brick of vertices at a time, with masks: a vertex `v` touches the cells `v − {0, 1}³`, so
/// the vertices touching an outside (inside) cell are the outside (inside) cells of the brick
/// and its seven lower neighbours grown by one towards +x, +y and +z ([`corners_of_cells`]).
/// Cells beyond the brick space count as outside, as in [`Flood::cell`].
fn touched_sides(band: &Band, walls: &BrickSet, flood: &Flood) -> Vec<u8> {
    let dims = walls.index.dims;
    let sides = |c: [i64; 3]| -> [BrickMask; 2] {
        if (0..3).any(|a| c[a] < 0 || c[a] >= dims[a] as i64) {
            return [[u64::MAX; 8], [0; 8]];
        }
        let key = walls.index.key([c[0] as u32, c[1] as u32, c[2] as u32]);
        [
            flood.outside_cells(walls, key),
            flood.inside_cells(walls, key),
        ]
    };
    let mut touches = vec![0u8; band.verts.len];
    band.verts.par_fill(
        &mut touches,
        || (),
        |_, _, b, mask, out| {
            let [outside, inside] = corners_of_cells(&sides, b);
            let mut i = 0;
            for_each_bit(mask, |x, y, z| {
                let (w, bit) = (z as usize, x + 8 * y);
                out[i] = if test(&outside, w, bit) {
                    TOUCHES_OUTSIDE
                } else {
                    0
                } | if test(&inside, w, bit) {
                    TOUCHES_INSIDE
                } else {
                    0
                };
                i += 1;
            });
        },
    );
    touches
}

/// The vertices of brick `b` that are corners of a member of each of two cell sets, given as
/// masks per brick by `cells` (brick coordinate → masks): the sets grown by one towards +x,
/// +y and +z, separably, with the faces carried in from the lower neighbours.
fn corners_of_cells(cells: &impl Fn([i64; 3]) -> [BrickMask; 2], b: [u32; 3]) -> [BrickMask; 2] {
    let grow = |m: [BrickMask; 2], lower: [BrickMask; 2], axis: usize| -> [BrickMask; 2] {
        std::array::from_fn(|k| {
            let (up, carry) = (shift(&m[k], axis, true), face_carry(&lower[k], axis, true));
            std::array::from_fn(|z| m[k][z] | up[z] | carry[z])
        })
    };
    let at = |d: [i64; 3]| [b[0] as i64 - d[0], b[1] as i64 - d[1], b[2] as i64 - d[2]];
    let along_x = |d: [i64; 3]| grow(cells(at(d)), cells(at([d[0] + 1, d[1], d[2]])), 0);
    let along_y = |dz: i64| grow(along_x([0, 0, dz]), along_x([0, 1, dz]), 1);
    grow(along_y(0), along_y(1), 2)
}

/// Side of a vertex from the cells it touches: outside if any is outside, else inside if
/// any is inside; `Unknown` where all eight are wall cells.
fn side_from_touches(touches: u8) -> Side {
    if touches & TOUCHES_OUTSIDE != 0 {
        Side::Outside
    } else if touches & TOUCHES_INSIDE != 0 {
        Side::Inside
    } else {
        Side::Unknown
    }
}

/// Resolves `Unknown` vertices through unblocked edges, level by level: a vertex decided in
/// level k sees only vertices decided before it, and one that sees both sides sides with
/// inside. Each level only looks at the undecided neighbours of the previous level, so the
/// work is linear in the vertices reached; the levels make the result independent of order.
/// What stays unknown is sealed in by triangles on every side (inside a closed part thinner
/// than a cell, or a pocket between sheets): [`crate::stages::inside::sealed::decide_sealed`] decides it.
fn resolve_enclosed(band: &Band, vox: &Voxelization, side: &mut [Side]) {
    let ids: Vec<u32> = (0..side.len() as u32)
        .filter(|&i| side[i as usize] == Side::Unknown)
        .collect();
    let mut candidates: Vec<(u32, [u32; 3])> = ids
        .iter()
        .copied()
        .zip(band.verts.coords_of(&ids))
        .collect();
    loop {
        let decided: Vec<(u32, [u32; 3], Side)> = candidates
            .par_iter()
            .filter_map(|&(i, c)| {
                let mut seen_out = false;
                for (j, _) in open_neighbours(band, vox, c) {
                    match side[j as usize] {
                        Side::Inside => return Some((i, c, Side::Inside)),
                        Side::Outside => seen_out = true,
                        Side::Unknown => {}
                    }
                }
                seen_out.then_some((i, c, Side::Outside))
            })
            .collect();
        if decided.is_empty() {
            break;
        }
        for &(i, _, s) in &decided {
            side[i as usize] = s;
        }
        candidates = decided
            .iter()
            .flat_map(|&(_, c, _)| open_neighbours(band, vox, c))
            .filter(|&(j, _)| side[j as usize] == Side::Unknown)
            .collect();
        candidates.sort_unstable_by_key(|&(j, _)| j);
        candidates.dedup_by_key(|&mut (j, _)| j);
    }
}

/// Evidence per wall cell, dense per wall brick (local index x + 8y + 64z): +1 for each crossed
/// edge of the cell whose ends are on the same side, −1 for each whose ends differ — or lie in
/// a wholly nested region and the one it is nested in ([`Nesting::separates`]): the surface of
/// a solid modelled inside a solid bounds no material, so it is neither a sheet nor kept.
///
/// In parallel over wall bricks, each gathering the crossed edges around its own cells: an
/// edge along `axis` from vertex `v` borders the cells `v − {0, 1}` along the two other axes,
/// so a brick's cells see the edges of its own blocked brick and of the first layer of its
/// three upper neighbours across those axes. A cell has at most 12 edges, so the sums never
/// saturate and do not depend on the order they are added in.
fn edge_evidence(
    band: &Band,
    vox: &Voxelization,
    side: &[Side],
    nesting: &Nesting,
) -> Vec<[i8; 512]> {
    let walls = &vox.walls;
    (0..walls.keys.len())
        .into_par_iter()
        .map(|s| {
            let b = walls.index.coord(walls.keys[s] as usize);
            let mut evidence = [0i8; 512];
            for (axis, set) in vox.blocked.iter().enumerate() {
                let (pb, pc) = ((axis + 1) % 3, (axis + 2) % 3);
                for d in 0..4 {
                    let (up_b, up_c) = (d & 1 == 1, d >> 1 == 1);
                    let mut nb = [b[0] as i64, b[1] as i64, b[2] as i64];
                    nb[pb] += i64::from(up_b);
                    nb[pc] += i64::from(up_c);
                    let Some(t) = set.index.slot(nb) else {
                        continue;
                    };
                    // In an upper neighbour only its first layer borders this brick's cells.
                    let mut mask = set.masks[t];
                    for (shifted, a) in [(up_b, pb), (up_c, pc)] {
                        if shifted {
                            mask = first_layer(&mask, a);
                        }
                    }
                    for_each_bit(&mask, |x, y, z| {
                        let v = [
                            nb[0] * 8 + x as i64,
                            nb[1] * 8 + y as i64,
                            nb[2] * 8 + z as i64,
                        ];
                        let mut u = v;
                        u[axis] += 1;
                        let (Some(i), Some(j)) = (band.verts.id(v), band.verts.id(u)) else {
                            return;
                        };
                        let (si, sj) = (side[i as usize], side[j as usize]);
                        let separate = si != sj || (si == Side::Inside && nesting.separates(i, j));
                        let vote: i8 = if separate { -1 } else { 1 };
                        for dd in 0..4i64 {
                            let mut cell = v;
                            cell[pb] -= dd & 1;
                            cell[pc] -= dd >> 1;
                            if (0..3).any(|a| cell[a] < 0 || cell[a] >> 3 != b[a] as i64) {
                                continue;
                            }
                            let local = (cell[0] & 7) + 8 * (cell[1] & 7) + 64 * (cell[2] & 7);
                            let e = &mut evidence[local as usize];
                            *e = e.saturating_add(vote);
                        }
                    });
                }
            }
            evidence
        })
        .collect()
}

/// The bits of `m` whose local coordinate along `axis` is 0.
fn first_layer(m: &BrickMask, axis: usize) -> BrickMask {
    match axis {
        0 => m.map(|w| w & X0),
        1 => m.map(|w| w & Y0),
        _ => std::array::from_fn(|z| if z == 0 { m[0] } else { 0 }),
    }
}

/// Wall cells that belong to a thin part: the evidence summed over the 3×3×3 cells around the
/// cell is not negative. A sum of 0 — no crossed edge nearby, as for a sliver of a sheet
/// narrower than a voxel — is thin too: only a surface that separates inside from outside can
/// keep φ = ±UDF. Per brick, a 10³ window of evidence (the brick and a one-cell halo) is box
/// filtered separably.
fn thin_cells(walls: &BrickSet, evidence: &[[i8; 512]]) -> Vec<BrickMask> {
    (0..walls.keys.len())
        .into_par_iter()
        .map(|s| {
            let b = walls.index.coord(walls.keys[s] as usize);
            let mut win = [0i16; 1000];
            let at = |x: usize, y: usize, z: usize| x + 10 * y + 100 * z;
            for off in cube_offsets(1) {
                let nb = [
                    b[0] as i64 + off[0],
                    b[1] as i64 + off[1],
                    b[2] as i64 + off[2],
                ];
                let Some(t) = walls.index.slot(nb) else {
                    continue;
                };
                // Local range of the neighbour that falls into the window.
                let range = |o: i64| match o {
                    -1 => 7..8,
                    0 => 0..8,
                    _ => 0..1,
                };
                for z in range(off[2]) {
                    for y in range(off[1]) {
                        for x in range(off[0]) {
                            let wx = (x as i64 + 8 * off[0] + 1) as usize;
                            let wy = (y as i64 + 8 * off[1] + 1) as usize;
                            let wz = (z as i64 + 8 * off[2] + 1) as usize;
                            win[at(wx, wy, wz)] = evidence[t][x + 8 * y + 64 * z] as i16;
                        }
                    }
                }
            }
            for axis in 0..3 {
                let prev = win;
                for z in 0..10 {
                    for y in 0..10 {
                        for x in 0..10 {
                            let p = [x, y, z];
                            let mut sum = prev[at(x, y, z)];
                            if p[axis] > 0 {
                                let mut q = p;
                                q[axis] -= 1;
                                sum += prev[at(q[0], q[1], q[2])];
                            }
                            if p[axis] < 9 {
                                let mut q = p;
                                q[axis] += 1;
                                sum += prev[at(q[0], q[1], q[2])];
                            }
                            win[at(x, y, z)] = sum;
                        }
                    }
                }
            }
            let mut thin = [0u64; 8];
            for_each_bit(&walls.masks[s], |x, y, z| {
                if win[at(x as usize + 1, y as usize + 1, z as usize + 1)] >= 0 {
                    thin[z as usize] |= 1u64 << (x + 8 * y);
                }
            });
            thin
        })
        .collect()
}

/// Whether the surface point `p` lies in a thin wall cell. The cell holding the closest
/// point touches the surface; a point on a cell face (or rounded to f32 next to one) may name
/// either neighbour, so both are tried.
fn thin_at(walls: &BrickSet, thin_cells: &[BrickMask], p: [f32; 3]) -> bool {
    (0..8)
        .find_map(|d| {
            let c: [i64; 3] = std::array::from_fn(|a| {
                let e = if (d >> a) & 1 == 0 { -1e-3 } else { 1e-3 };
                (p[a] + e).floor() as i64
            });
            if c.iter().any(|&x| x < 0) {
                return None;
            }
            let (b, w, bit) = split([c[0] as u32, c[1] as u32, c[2] as u32]);
            let slot = walls.index.slot([b[0] as i64, b[1] as i64, b[2] as i64])?;
            test(&walls.masks[slot], w, bit).then(|| test(&thin_cells[slot], w, bit))
        })
        .unwrap_or(false)
}

/// The sides of the core band's vertices (the corners of the wall cells) as the flood and
/// the unblocked edges give them, with the cells each touches ([`CoreSigns::touches`]).
/// Vertices sealed in by triangles on every side stay `Unknown`.
pub fn vertex_sides(band: &Band, vox: &Voxelization, flood: &Flood) -> (Vec<u8>, Vec<Side>) {
    let touches = touched_sides(band, &vox.walls, flood);
    let mut side: Vec<Side> = touches.iter().map(|&t| side_from_touches(t)).collect();
    resolve_enclosed(band, vox, &mut side);
    (touches, side)
}

/// Without the inside test: every vertex sealed in by triangles on every side (still
/// `Unknown` after [`vertex_sides`]) is outside, as the conversion decided before the test.
pub fn sealed_to_outside(side: &mut [Side]) {
    for s in side.iter_mut().filter(|s| **s == Side::Unknown) {
        *s = Side::Outside;
    }
}

/// Decides which core vertices belong to thin shells, once every side is known (see
/// [`vertex_sides`] and [`crate::stages::inside::sealed::decide_sealed`]).
pub fn compute_signs(
    band: &Band,
    vox: &Voxelization,
    touches: Vec<u8>,
    side: Vec<Side>,
    nesting: &Nesting,
) -> CoreSigns {
    let evidence = edge_evidence(band, vox, &side, nesting);
    let thin_cells = thin_cells(&vox.walls, &evidence);
    let thin = thin_flags(band, &vox.walls, &thin_cells);
    CoreSigns {
        signs: Signs { side, thin },
        touches,
        thin_cells,
    }
}

/// Whether each band vertex's closest surface point lies in a thin wall cell.
fn thin_flags(band: &Band, walls: &BrickSet, thin_cells: &[BrickMask]) -> Vec<bool> {
    band.nearest
        .par_iter()
        .map(|near| thin_at(walls, thin_cells, near.point))
        .collect()
}

/// Signs of the ring's own vertices (corners of the [`crate::stages::ring`] cells that are not
/// corners of wall cells), with the thin wall cells the core band found. Every such vertex
/// touches only surface-free cells, so its side is known from the flood.
pub fn ring_signs(band: &Band, walls: &BrickSet, flood: &Flood, core: &CoreSigns) -> Signs {
    let side = touched_sides(band, walls, flood)
        .into_iter()
        .map(|t| match side_from_touches(t) {
            // Not reached: every corner of a surface-free cell touches it.
            Side::Unknown => Side::Outside,
            s => s,
        })
        .collect();
    Signs {
        side,
        thin: thin_flags(band, walls, &core.thin_cells),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::normalization::Normalization;
    use crate::grid::{dilate, Dilation, Numbered};
    use crate::mesh::GridMesh;
    use crate::shapes::{cube_with_hole, merge, open_cylinder, sphere};
    use crate::stages::band::{compute_band, triangle_planes, CORE_REACH};
    use crate::stages::flood::{flood_outside, CellSide};
    use crate::stages::voxelize::voxelize;

    const N: u32 = 48;

    /// A closed sphere, an open tube and a cube with a hole, in grid coordinates at `N`.
    fn fixture() -> (Voxelization, Flood, Band) {
        let mesh = merge(&[
            sphere([0.0; 3], 1.0, 24),
            open_cylinder([2.5, 0.0], 0.6, -1.0, 1.0, 24),
            cube_with_hole([-1.5, 1.5, -0.5], [-0.5, 2.5, 0.5], 0.3),
        ]);
        let norm = Normalization::fit(mesh.bounds().unwrap(), N, 2);
        let grid = GridMesh {
            verts: mesh
                .positions
                .iter()
                .map(|p| norm.source_to_grid(p.map(f64::from), N))
                .collect(),
            tris: mesh.triangles.clone(),
        };
        let vox = voxelize(&grid, N);
        let flood = flood_outside(&vox.walls);
        let verts = dilate(&vox.walls, N, Dilation::Corners);
        let band = compute_band(&grid, &triangle_planes(&grid), verts, CORE_REACH);
        (vox, flood, band)
    }

    #[test]
    fn touched_sides_match_the_cells_around_each_vertex() {
        let (vox, flood, band) = fixture();
        let touches = touched_sides(&band, &vox.walls, &flood);
        let mut seen = 0;
        for (i, c) in band.verts.coords().into_iter().enumerate() {
            let mut want = 0;
            for d in 0..8i64 {
                let cell = [
                    c[0] as i64 - (d & 1),
                    c[1] as i64 - ((d >> 1) & 1),
                    c[2] as i64 - (d >> 2),
                ];
                want |= match flood.cell(&vox.walls, cell) {
                    CellSide::Outside => TOUCHES_OUTSIDE,
                    CellSide::Inside => TOUCHES_INSIDE,
                    CellSide::Wall => 0,
                };
            }
            assert_eq!(touches[i], want, "vertex {c:?}");
            seen |= want;
        }
        assert_eq!(seen, TOUCHES_OUTSIDE | TOUCHES_INSIDE, "both sides occur");
    }

    #[test]
    fn edge_evidence_sums_the_votes_of_each_cells_crossed_edges() {
        let (vox, flood, band) = fixture();
        let touches = touched_sides(&band, &vox.walls, &flood);
        let mut side: Vec<Side> = touches.iter().map(|&t| side_from_touches(t)).collect();
        resolve_enclosed(&band, &vox, &mut side);
        let got = edge_evidence(&band, &vox, &side, &Nesting::default());
        // Each crossed edge adds its vote to the (up to) four cells around it.
        let walls = &vox.walls;
        let mut want = vec![[0i8; 512]; walls.keys.len()];
        let mut votes = [0; 2];
        for (axis, set) in vox.blocked.iter().enumerate() {
            let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
            for v in Numbered::new(set.clone()).coords() {
                let v = v.map(i64::from);
                let mut u = v;
                u[axis] += 1;
                let (Some(i), Some(j)) = (band.verts.id(v), band.verts.id(u)) else {
                    continue;
                };
                let same = side[i as usize] == side[j as usize];
                votes[usize::from(same)] += 1;
                for d in 0..4i64 {
                    let mut cell = v;
                    cell[b] -= d & 1;
                    cell[c] -= d >> 1;
                    if cell.iter().any(|&x| x < 0) {
                        continue;
                    }
                    let (bk, w, bit) = split(cell.map(|x| x as u32));
                    if let Some(s) = walls.index.slot(bk.map(i64::from)) {
                        want[s][w * 64 + bit as usize] += if same { 1 } else { -1 };
                    }
                }
            }
        }
        assert!(votes[0] > 0 && votes[1] > 0, "both kinds of vote occur");
        assert!(got == want);
    }
}
