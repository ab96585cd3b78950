//! Stage 5: exact unsigned distance and closest point on the grid vertices near the surface.
//!
//! The distances are computed for the corners of a set of cells in two calls: first the
//! corners of the wall cells (the core band, every vertex within √3 of the surface), then,
//! once signs are known, the corners of the few cells next to the walls that a thin shell
//! reaches (`crate::stages::ring`). Only triangles within the reach of a brick are binned to it, and
//! each brick scans its own triangles — no per-vertex tree query.

use crate::grid::{for_each_bit, BrickMask, BrickSet, Numbered, BRICK};
use crate::mesh::triangle::closest_point_on_triangle;
use crate::mesh::GridMesh;
use crate::stages::voxelize::triangle_box_overlap;
use crate::vec3::{cross, dot, sub};
use rayon::prelude::*;

/// Farthest a corner of a cell next to a wall cell can be from the surface: it is within the
/// 2×2×2-cell box around a surface point, whose diagonal is 2√3 ≈ 3.46.
pub const REACH: f64 = 3.5;

/// Farthest a corner of a wall cell can be from the surface: the cell touches the surface,
/// and its diagonal is √3 ≈ 1.732.
pub const CORE_REACH: f64 = 1.75;

/// Vertices with their distance and closest point.
#[derive(Debug, Clone)]
pub struct Band {
    /// The vertices, numbered.
    pub verts: Numbered,
    /// Closest surface point and unsigned distance per vertex.
    pub nearest: Vec<Nearest>,
}

/// A vertex's closest surface point (grid coordinates) and its distance (voxels).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Nearest {
    /// Closest point on the surface.
    pub point: [f32; 3],
    /// Unsigned distance to it.
    pub udf: f32,
}

/// For each brick of `verts`, the triangles within `reach` of it, ascending (CSR layout).
fn bin_triangles(mesh: &GridMesh, verts: &BrickSet, reach: f64) -> (Vec<u32>, Vec<u32>) {
    let index = &verts.index;
    let mut pairs: Vec<u64> = (0..mesh.tris.len())
        .into_par_iter()
        .with_min_len(256)
        .fold(Vec::new, |mut out: Vec<u64>, t| {
            let tri = mesh.tri(t);
            let mut lo = [0i64; 3];
            let mut hi = [0i64; 3];
            for a in 0..3 {
                let mn = tri[0][a].min(tri[1][a]).min(tri[2][a]) - reach;
                let mx = tri[0][a].max(tri[1][a]).max(tri[2][a]) + reach;
                lo[a] = ((mn / BRICK as f64).floor() as i64).max(0);
                hi[a] = ((mx / BRICK as f64).floor() as i64).min(index.dims[a] as i64 - 1);
            }
            for bz in lo[2]..=hi[2] {
                for by in lo[1]..=hi[1] {
                    for bx in lo[0]..=hi[0] {
                        let Some(slot) = index.slot([bx, by, bz]) else {
                            continue;
                        };
                        let center = [
                            bx as f64 * 8.0 + 3.5,
                            by as f64 * 8.0 + 3.5,
                            bz as f64 * 8.0 + 3.5,
                        ];
                        if triangle_box_overlap(&tri, center, 3.5 + reach) {
                            out.push(((slot as u64) << 32) | t as u64);
                        }
                    }
                }
            }
            out
        })
        .reduce(Vec::new, |mut a, b| {
            a.extend(b);
            a
        });
    pairs.par_sort_unstable();
    let bricks = verts.keys.len();
    let mut starts = vec![0u32; bricks + 1];
    for &p in &pairs {
        starts[(p >> 32) as usize + 1] += 1;
    }
    for i in 0..bricks {
        starts[i + 1] += starts[i];
    }
    let tris = pairs.iter().map(|&p| p as u32).collect();
    (starts, tris)
}

/// Per-thread buffers of one brick's scan, indexed by local vertex position (x + 8y + 64z).
struct BrickScratch {
    best: Vec<f64>,
    point: Vec<[f64; 3]>,
}

impl BrickScratch {
    fn new() -> Self {
        Self {
            best: vec![f64::INFINITY; 512],
            point: vec![[0.0; 3]; 512],
        }
    }
}

/// One brick's scan: the mesh with its [`triangle_planes`], the brick's triangles (ascending)
/// and its lowest vertex.
struct BrickScan<'a> {
    mesh: &'a GridMesh,
    planes: &'a [[f64; 4]],
    tris: &'a [u32],
    base: [i64; 3],
}

/// Updates the best distance of the vertices in `mask` that lie within `reach` of each
/// triangle's bounding box. Triangles come in ascending order and only a strictly smaller
/// distance replaces the best, so ties go to the lowest triangle index.
fn scan_pass(brick: &BrickScan<'_>, mask: &BrickMask, reach: f64, scratch: &mut BrickScratch) {
    let BrickScan {
        mesh,
        planes,
        tris,
        base,
    } = *brick;
    for &t in tris {
        let tri = mesh.tri(t as usize);
        let pl = planes[t as usize];
        let mut lo = [0i64; 3];
        let mut hi = [0i64; 3];
        let mut empty = false;
        for a in 0..3 {
            let mn = tri[0][a].min(tri[1][a]).min(tri[2][a]) - reach;
            let mx = tri[0][a].max(tri[1][a]).max(tri[2][a]) + reach;
            lo[a] = (mn.ceil() as i64).max(base[a]) - base[a];
            hi[a] = (mx.floor() as i64).min(base[a] + 7) - base[a];
            empty |= lo[a] > hi[a];
        }
        if empty {
            continue;
        }
        for z in lo[2]..=hi[2] {
            let word = mask[z as usize];
            if word == 0 {
                continue;
            }
            for y in lo[1]..=hi[1] {
                let row = (word >> (8 * y)) & 0xFF;
                if row == 0 {
                    continue;
                }
                for x in lo[0]..=hi[0] {
                    if (row >> x) & 1 == 0 {
                        continue;
                    }
                    let local = (x + 8 * y + 64 * z) as usize;
                    let p = [
                        (base[0] + x) as f64,
                        (base[1] + y) as f64,
                        (base[2] + z) as f64,
                    ];
                    let plane = pl[0] * p[0] + pl[1] * p[1] + pl[2] * p[2] - pl[3];
                    let best = scratch.best[local];
                    if plane * plane >= best {
                        continue;
                    }
                    let q = closest_point_on_triangle(p, &tri);
                    let d = sub(p, q);
                    let d2 = dot(d, d);
                    if d2 < best {
                        scratch.best[local] = d2;
                        scratch.point[local] = q;
                    }
                }
            }
        }
    }
}

/// Distances and closest points of one brick's vertices, in local order: a pass with
/// [`CORE_REACH`] settles every vertex within it (all corners of wall cells); if `reach` is
/// larger, the rest are rescanned with it.
fn scan_brick(
    brick: &BrickScan<'_>,
    mask: &BrickMask,
    reach: f64,
    scratch: &mut BrickScratch,
    out: &mut [Nearest],
) {
    let base = brick.base;
    scratch.best.fill(f64::INFINITY);
    let near = CORE_REACH.min(reach);
    scan_pass(brick, mask, near, scratch);
    if reach > near {
        let mut far = [0u64; 8];
        for_each_bit(mask, |x, y, z| {
            let local = (x + 8 * y + 64 * z) as usize;
            if scratch.best[local] > near * near {
                scratch.best[local] = f64::INFINITY;
                far[z as usize] |= 1u64 << (x + 8 * y);
            }
        });
        if !crate::grid::is_empty(&far) {
            scan_pass(brick, &far, reach, scratch);
        }
    }
    let mut i = 0;
    for_each_bit(mask, |x, y, z| {
        let local = (x + 8 * y + 64 * z) as usize;
        let best = scratch.best[local];
        out[i] = if best.is_finite() {
            let q = scratch.point[local];
            Nearest {
                point: [q[0] as f32, q[1] as f32, q[2] as f32],
                udf: best.sqrt() as f32,
            }
        } else {
            // Unreachable by the reach argument; keep the vertex far.
            let p = [base[0] + x as i64, base[1] + y as i64, base[2] + z as i64];
            Nearest {
                point: [p[0] as f32, p[1] as f32, p[2] as f32],
                udf: reach as f32,
            }
        };
        i += 1;
    });
}

/// Computes, for every vertex of `verts`, its exact distance to the surface and its closest
/// point (`planes` from [`triangle_planes`]). `reach` bounds how far any of them can be from the surface ([`CORE_REACH`] for the
/// corners of wall cells, [`REACH`] for the corners of their neighbours). Ties go to the
/// lowest triangle index and a vertex's result depends only on the triangles within its
/// reach, so it does not depend on the thread count.
pub fn compute_band(mesh: &GridMesh, planes: &[[f64; 4]], verts: BrickSet, reach: f64) -> Band {
    let verts = Numbered::new(verts);
    let (starts, bins) = bin_triangles(mesh, &verts.set, reach);
    let mut nearest = vec![Nearest::default(); verts.len];
    verts.par_fill(
        &mut nearest,
        BrickScratch::new,
        |scratch, s, b, mask, out| {
            let brick = BrickScan {
                mesh,
                planes,
                tris: &bins[starts[s] as usize..starts[s + 1] as usize],
                base: [b[0] as i64 * 8, b[1] as i64 * 8, b[2] as i64 * 8],
            };
            scan_brick(&brick, mask, reach, scratch, out);
        },
    );
    Band { verts, nearest }
}

/// Each triangle's unit normal `n` and offset `n·a`, the plane [`compute_band`] uses to skip
/// triangles farther than a vertex's best distance. Computed once per mesh for every band.
pub fn triangle_planes(mesh: &GridMesh) -> Vec<[f64; 4]> {
    (0..mesh.tris.len())
        .map(|t| {
            let [a, b, c] = mesh.tri(t);
            let nrm = cross(sub(b, a), sub(c, a));
            let len = dot(nrm, nrm).sqrt();
            let nrm = [nrm[0] / len, nrm[1] / len, nrm[2] / len];
            [nrm[0], nrm[1], nrm[2], dot(nrm, a)]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{dilate, Dilation};
    use crate::stages::voxelize::voxelize;

    /// A torus crossed by a sphere, scaled and shifted off the lattice into a 48³ grid.
    fn crossed_shapes() -> (GridMesh, u32) {
        let mesh = crate::shapes::merge(&[
            crate::shapes::torus([0.0; 3], 1.0, 0.35, 24),
            crate::shapes::sphere([0.3, 0.2, 0.1], 0.5, 16),
        ]);
        let verts = mesh
            .positions
            .iter()
            .map(|p| {
                [
                    p[0] as f64 * 17.3 + 24.1,
                    p[1] as f64 * 17.3 + 23.7,
                    p[2] as f64 * 17.3 + 24.3,
                ]
            })
            .collect();
        let grid = GridMesh {
            verts,
            tris: mesh.triangles,
        };
        (grid, 48)
    }

    /// The nearest point of `p` over every triangle, ties to the lowest index.
    fn nearest_by_brute_force(mesh: &GridMesh, p: [f64; 3]) -> Nearest {
        let (mut best, mut point) = (f64::INFINITY, p);
        for t in 0..mesh.tris.len() {
            let q = closest_point_on_triangle(p, &mesh.tri(t));
            let d = sub(p, q);
            let d2 = dot(d, d);
            if d2 < best {
                (best, point) = (d2, q);
            }
        }
        Nearest {
            point: point.map(|c| c as f32),
            udf: best.sqrt() as f32,
        }
    }

    #[test]
    fn band_distances_are_the_exact_minimum_over_all_triangles() {
        let (mesh, n) = crossed_shapes();
        let planes = triangle_planes(&mesh);
        let walls = voxelize(&mesh, n).walls;
        // The core band (corners of the wall cells), and the corners of the cells around the
        // walls, which the far pass of REACH settles.
        let core = dilate(&walls, n, Dilation::Corners);
        let around = dilate(&dilate(&walls, n, Dilation::Box), n, Dilation::Corners);
        for (verts, reach) in [(core, CORE_REACH), (around, REACH)] {
            let band = compute_band(&mesh, &planes, verts, reach);
            let coords = band.verts.coords();
            assert!(coords.len() > 1000, "{} vertices", coords.len());
            for (c, got) in coords.iter().zip(&band.nearest) {
                let want = nearest_by_brute_force(&mesh, c.map(|v| v as f64));
                assert_eq!(
                    (got.udf.to_bits(), got.point.map(f32::to_bits)),
                    (want.udf.to_bits(), want.point.map(f32::to_bits)),
                    "vertex {c:?} (reach {reach}): {got:?} against {want:?}"
                );
            }
        }
    }
}
