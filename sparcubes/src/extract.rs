//! Stage 7: sparse marching cubes over the active cells with the deformed vertex positions.
//!
//! Each active cell looks up its 8 corners, resolves its ambiguous faces with the asymptotic
//! decider (which only reads the face's own values, so both cells sharing a face agree), and
//! emits the triangles of [`crate::mc_table`]. Crossing points are keyed by their grid edge
//! (`lower vertex index × 3 + axis`) and computed from that edge's two vertices only, so the
//! cells sharing an edge share one vertex and the mesh is indexed and watertight. Cells are
//! processed in parallel chunks; vertices are numbered by key, so the output is the same
//! bytes whatever the thread count.

use crate::cubes::SparseCubes;
use crate::mc_table::{self, CENTRE, EDGES, FACE_CORNERS};
use crate::mesh::TriMesh;
use crate::normalize::Normalization;
use rayon::prelude::*;

/// Cells per parallel work item (fixed, so the work split never depends on the thread count).
const CHUNK: usize = 4096;

/// Keys of centre vertices have this bit set; the rest is `cell index << 3 | centre`.
const CENTRE_KEY: u64 = 1 << 63;

/// Extracts the closed, 2-manifold, outward-oriented mesh of `cubes`, in grid coordinates
/// (voxels). Use [`crate::Normalization::grid_to_source`] (or [`extract_to_source`]) to map
/// it back.
///
/// The result is closed when `cubes.cells` holds every cell with a sign change (zero counts
/// as outside); a cell whose corners are not all in `coords` is skipped.
pub fn extract(cubes: &SparseCubes) -> TriMesh {
    let n = cubes.coords.len().min(cubes.sdf.len());
    let chunks: Vec<(Vec<u64>, Vec<[f32; 3]>)> = cubes
        .cells
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(ci, cells)| extract_chunk(cubes, n, ci * CHUNK, cells))
        .collect();

    let total: usize = chunks.iter().map(|c| c.0.len()).sum();
    let mut keys = Vec::with_capacity(total);
    let mut points = Vec::with_capacity(total);
    for (k, p) in chunks {
        keys.extend(k);
        points.extend(p);
    }
    // Number vertices by key: crossing points in edge-key order (a dense table over the
    // grid edges of active vertices), then centres in cell order; both orders are fixed by the
    // data alone.
    const UNSET: u32 = u32::MAX;
    let mut id_of_edge = vec![UNSET; 3 * n];
    let mut centres: Vec<(u64, u32)> = Vec::new();
    for (slot, &key) in keys.iter().enumerate() {
        if key & CENTRE_KEY != 0 {
            if centres.last().is_none_or(|c| c.0 != key) {
                centres.push((key, slot as u32));
            }
        } else if id_of_edge[key as usize] == UNSET {
            id_of_edge[key as usize] = slot as u32;
        }
    }
    debug_assert!(centres.windows(2).all(|w| w[0].0 < w[1].0));
    let mut positions = Vec::new();
    for first in id_of_edge.iter_mut().filter(|s| **s != UNSET) {
        positions.push(points[*first as usize]);
        *first = positions.len() as u32 - 1;
    }
    let first_centre = positions.len() as u32;
    positions.extend(centres.iter().map(|&(_, slot)| points[slot as usize]));
    let index: Vec<u32> = keys
        .par_iter()
        .map(|&key| {
            if key & CENTRE_KEY != 0 {
                // Centre keys rise with the slot, so a binary search finds them.
                let i = centres.partition_point(|c| c.0 < key);
                first_centre + i as u32
            } else {
                id_of_edge[key as usize]
            }
        })
        .collect();
    let triangles = index.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    TriMesh::new(positions, triangles)
}

/// [`extract`], mapped to the source frame with `cubes.normalization`.
pub fn extract_to_source(cubes: &SparseCubes) -> TriMesh {
    let mut mesh = extract(cubes);
    to_source(&mut mesh, &cubes.normalization, cubes.resolution);
    mesh
}

/// Maps a mesh in grid coordinates at resolution `resolution` to the source frame.
pub fn to_source(mesh: &mut TriMesh, normalization: &Normalization, resolution: u32) {
    mesh.positions.par_iter_mut().for_each(|p| {
        let g = [p[0] as f64, p[1] as f64, p[2] as f64];
        let s = normalization.grid_to_source(g, resolution);
        *p = [s[0] as f32, s[1] as f32, s[2] as f32];
    });
}

/// Index of the first coord `>= target` at or after `from`, by galloping.
#[inline]
fn gallop(coords: &[[u16; 3]], from: usize, target: [u16; 3]) -> usize {
    if from >= coords.len() || coords[from] >= target {
        return from;
    }
    let mut step = 1;
    let mut lo = from;
    while lo + step < coords.len() && coords[lo + step] < target {
        lo += step;
        step *= 2;
    }
    let hi = (lo + step + 1).min(coords.len());
    lo + coords[lo..hi].partition_point(|c| *c < target)
}

/// Triangles of one chunk of cells, as vertex keys and positions (3 per triangle).
fn extract_chunk(
    cubes: &SparseCubes,
    n: usize,
    first_cell: usize,
    cells: &[[u16; 3]],
) -> (Vec<u64>, Vec<[f32; 3]>) {
    let table = mc_table::table();
    let coords = &cubes.coords[..n];
    let sdf = &cubes.sdf[..n];
    let pos = |i: usize| -> [f64; 3] {
        let c = coords[i];
        let d = cubes.deformation.get(i).copied().unwrap_or([0.0; 3]);
        [
            c[0] as f64 + d[0] as f64,
            c[1] as f64 + d[1] as f64,
            c[2] as f64 + d[2] as f64,
        ]
    };
    let mut keys = Vec::new();
    let mut points = Vec::new();
    // One monotone cursor per corner column (dx, dy): the targets rise with the cells.
    let mut cursor = [0usize; 4];
    for (ci, &cell) in cells.iter().enumerate() {
        let mut idx = [0usize; 8];
        let mut ok = true;
        for (col, cur) in cursor.iter_mut().enumerate() {
            let (dx, dy) = ((col & 1) as u16, (col >> 1) as u16);
            let (Some(x), Some(y), Some(z1)) = (
                cell[0].checked_add(dx),
                cell[1].checked_add(dy),
                cell[2].checked_add(1),
            ) else {
                ok = false;
                break;
            };
            *cur = gallop(coords, *cur, [x, y, cell[2]]);
            let i = *cur;
            if i + 1 < n && coords[i] == [x, y, cell[2]] && coords[i + 1] == [x, y, z1] {
                idx[col] = i;
                idx[col + 4] = i + 1;
            } else {
                ok = false;
            }
        }
        if !ok {
            continue;
        }
        let mut mask = 0u8;
        for (c, &i) in idx.iter().enumerate() {
            if sdf[i] < 0.0 {
                mask |= 1 << c;
            }
        }
        if mask == 0 || mask == 0xff {
            continue;
        }
        let mut bits = 0u8;
        let ambiguous = mc_table::ambiguous_faces(mask);
        for (f, fc) in FACE_CORNERS.iter().enumerate() {
            if ambiguous >> f & 1 == 1 && mc_table::inside_joined(fc.map(|c| sdf[idx[c as usize]]))
            {
                bits |= 1 << f;
            }
        }
        let case = table.case(mask, bits);
        let edge_point = |e: u8| -> (u64, [f64; 3]) {
            let (a, b, axis) = EDGES[e as usize];
            let (ia, ib) = (idx[a as usize], idx[b as usize]);
            let (sa, sb) = (sdf[ia] as f64, sdf[ib] as f64);
            let mut w = sa / (sa - sb);
            if !w.is_finite() {
                w = 0.5;
            }
            let w = w.clamp(0.0, 1.0);
            let (pa, pb) = (pos(ia), pos(ib));
            let p = [
                pa[0] + w * (pb[0] - pa[0]),
                pa[1] + w * (pb[1] - pa[1]),
                pa[2] + w * (pb[2] - pa[2]),
            ];
            (ia as u64 * 3 + axis as u64, p)
        };
        let centre = |k: u8| -> (u64, [f64; 3]) {
            let edges = &case.centres[k as usize];
            let mut s = [0.0; 3];
            for &e in edges {
                let p = edge_point(e).1;
                s = [s[0] + p[0], s[1] + p[1], s[2] + p[2]];
            }
            let m = edges.len() as f64;
            let key = CENTRE_KEY | ((first_cell + ci) as u64) << 3 | k as u64;
            (key, [s[0] / m, s[1] / m, s[2] / m])
        };
        for tri in &case.triangles {
            for &v in tri {
                let (key, p) = if v < CENTRE {
                    edge_point(v)
                } else {
                    centre(v - CENTRE)
                };
                keys.push(key);
                points.push([p[0] as f32, p[1] as f32, p[2] as f32]);
            }
        }
    }
    (keys, points)
}

/// Builds sparse cubes by sampling `field` (sdf in voxels, deformation in voxels) on every grid
/// vertex of the box `lo..=hi`: the active cells are the cells of the box with a sign change
/// and the active vertices their corners. Meant for tests and examples with analytic fields;
/// normalization is the identity.
pub fn sample_box<F>(resolution: u32, lo: [u16; 3], hi: [u16; 3], field: F) -> SparseCubes
where
    F: Fn([u16; 3]) -> (f32, [f32; 3]) + Sync,
{
    let dim = |a: usize| (hi[a].saturating_sub(lo[a]) as usize) + 1;
    let (nx, ny, nz) = (dim(0), dim(1), dim(2));
    let at = |x: usize, y: usize, z: usize| (x * ny + y) * nz + z;
    let coord =
        |x: usize, y: usize, z: usize| [lo[0] + x as u16, lo[1] + y as u16, lo[2] + z as u16];
    let values: Vec<(f32, [f32; 3])> = (0..nx * ny * nz)
        .into_par_iter()
        .map(|i| field(coord(i / (ny * nz), i / nz % ny, i % nz)))
        .collect();
    let mut used = vec![false; values.len()];
    let mut cells = Vec::new();
    for x in 0..nx.saturating_sub(1) {
        for y in 0..ny.saturating_sub(1) {
            for z in 0..nz.saturating_sub(1) {
                let corners = (0..8).map(|c| at(x + (c & 1), y + (c >> 1 & 1), z + (c >> 2)));
                let inside = corners.clone().filter(|&i| values[i].0 < 0.0).count();
                if inside != 0 && inside != 8 {
                    cells.push(coord(x, y, z));
                    corners.for_each(|i| used[i] = true);
                }
            }
        }
    }
    let mut cubes = SparseCubes {
        resolution,
        ..Default::default()
    };
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                let i = at(x, y, z);
                if used[i] {
                    cubes.coords.push(coord(x, y, z));
                    cubes.sdf.push(values[i].0);
                    cubes.deformation.push(values[i].1);
                }
            }
        }
    }
    cubes.cells = cells;
    cubes
}
