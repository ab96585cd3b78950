//! Stage 11: sparse marching cubes over the active cells with the deformed vertex positions.
//!
//! Each active cell looks up its 8 corners, resolves its ambiguous faces with the asymptotic
//! decider (which only reads the face's own values, so both cells sharing a face agree), and
//! emits the triangles of [`crate::stages::extract::mc_table`]. Crossing points are keyed by their grid edge
//! (`lower vertex index × 3 + axis`) and computed from that edge's two vertices only, so the
//! cells sharing an edge share one vertex and the mesh is indexed and watertight.
//!
//! Two passes over fixed chunks of cells, in parallel: the first finds each cell's corners
//! and case once, keeps them per chunk (16 bytes of corner indices and 2 of case a cell),
//! counts the chunk's triangles and centre vertices and marks the crossed edges in a bitmap;
//! the second reads the kept cases back and writes the triangles straight into the output,
//! numbering a crossing point by the rank of its edge in the bitmap and centres after them in
//! cell order. No per-triangle key list is built or sorted, and the output is the same bytes
//! whatever the thread count.

pub mod close_grid;
pub mod mc_table;

use crate::grid::cubes::{gallop, SparseCubes};
use crate::grid::normalization::Normalization;
use crate::mesh::TriMesh;
use mc_table::{Case, Table, CENTRE, EDGES, FACE_CORNERS};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};

/// Cells per parallel work item (fixed, so the work split never depends on the thread count).
const CHUNK: usize = 4096;

/// Extracts the closed, 2-manifold, outward-oriented mesh of `cubes`, in grid coordinates
/// (voxels). Use [`crate::Normalization::grid_to_source`] (or [`extract_to_source`]) to map
/// it back.
///
/// The result is closed when `cubes.cells` holds every cell with a sign change (zero counts
/// as outside); a cell whose corners are not all in `coords` is skipped.
pub fn extract(cubes: &SparseCubes) -> TriMesh {
    let n = cubes.coords.len().min(cubes.sdf.len());
    let table = mc_table::table();
    let (chunks, used) = find_cases(cubes, n, table);
    // Rank of each bitmap word: crossing points are numbered in edge-key order.
    let mut rank = Vec::with_capacity(used.len());
    let mut edge_points = 0u32;
    for w in &used {
        rank.push(edge_points);
        edge_points += w.count_ones();
    }

    // Pass 2: each chunk writes its triangles and centres into its own slices; crossing
    // points shared between chunks are stored through atomics (every writer stores the same
    // value, computed from the edge's two vertices only, so a point already stored is not
    // computed again).
    let total_triangles: usize = chunks.iter().map(|c| c.triangles).sum();
    let total_centres: usize = chunks.iter().map(|c| c.centres).sum();
    let mut triangles = vec![[0u32; 3]; total_triangles];
    let mut centre_points = vec![[0f32; 3]; total_centres];
    let shared: Vec<[AtomicU32; 3]> = (0..edge_points)
        .into_par_iter()
        .map(|_| [AtomicU32::new(0), AtomicU32::new(0), AtomicU32::new(0)])
        .collect();
    let mut work = Vec::with_capacity(chunks.len());
    let (mut tri_rest, mut centre_rest) = (&mut triangles[..], &mut centre_points[..]);
    let mut first_centre = edge_points;
    // Each chunk's kept cases move into its work item and are freed as soon as it is
    // written, so they are gone before the final position list is built.
    for chunk in chunks {
        let (tris, tail) = tri_rest.split_at_mut(chunk.triangles);
        tri_rest = tail;
        let (centres, tail) = centre_rest.split_at_mut(chunk.centres);
        centre_rest = tail;
        let next_centre = first_centre + chunk.centres as u32;
        work.push((chunk, tris, centres, first_centre));
        first_centre = next_centre;
    }
    work.into_par_iter()
        .for_each(|(chunk, tris, centres, first_centre)| {
            let (mut t, mut c) = (0, 0);
            for (corners, &[mask, bits]) in chunk.corners.iter().zip(&chunk.cases) {
                let idx = corner_indices(corners);
                let case = table.case(mask, bits);
                // Centre k of this cell, numbered among the cell's used centres.
                let used_centres = centres_used(case);
                for k in 0..case.centres.len() {
                    if used_centres >> k & 1 == 1 {
                        let p = centre_point(cubes, &idx, &case.centres[k]);
                        let slot = (used_centres & ((1 << k) - 1)).count_ones() as usize;
                        centres[c + slot] = to_f32(p);
                    }
                }
                let mut stored = 0u16;
                for tri in &case.triangles {
                    let mut ids = [0u32; 3];
                    for (id, &v) in ids.iter_mut().zip(tri) {
                        *id = if v < CENTRE {
                            let key = edge_key(&idx, v);
                            let (w, bit) = (key / 64, key % 64);
                            let i = rank[w] + (used[w] & ((1u64 << bit) - 1)).count_ones();
                            let point = &shared[i as usize];
                            if stored >> v & 1 == 0
                                && point.iter().all(|a| a.load(Ordering::Relaxed) == 0)
                            {
                                let p = to_f32(edge_point(cubes, &idx, v));
                                for a in 0..3 {
                                    point[a].store(p[a].to_bits(), Ordering::Relaxed);
                                }
                            }
                            stored |= 1 << v;
                            i
                        } else {
                            let k = v - CENTRE;
                            let slot = (used_centres & ((1 << k) - 1)).count_ones() as usize;
                            first_centre + (c + slot) as u32
                        };
                    }
                    tris[t] = ids;
                    t += 1;
                }
                c += used_centres.count_ones() as usize;
            }
        });
    let positions: Vec<[f32; 3]> = shared
        .par_iter()
        .map(|p| {
            p.each_ref()
                .map(|a| f32::from_bits(a.load(Ordering::Relaxed)))
        })
        .chain(centre_points.par_iter().copied())
        .collect();
    TriMesh::new(positions, triangles)
}

/// The cells of one chunk that have a case, in cell order, as pass 1 of [`extract`] found
/// them, with the chunk's counts.
#[derive(Default)]
struct ChunkCases {
    /// Per cell: the indices in `coords` of corners 0–3; corner `c + 4` is the vertex after
    /// corner `c` (one step up in z).
    corners: Vec<[u32; 4]>,
    /// Per cell: its corner mask and face bits, the arguments of [`Table::case`].
    cases: Vec<[u8; 2]>,
    /// Triangles of the chunk's cells.
    triangles: usize,
    /// Centre vertices the chunk's triangles use.
    centres: usize,
}

/// The eight corner indices of a cell kept by [`find_cases`].
#[inline]
fn corner_indices(corners: &[u32; 4]) -> [usize; 8] {
    let c = corners.map(|i| i as usize);
    [
        c[0],
        c[1],
        c[2],
        c[3],
        c[0] + 1,
        c[1] + 1,
        c[2] + 1,
        c[3] + 1,
    ]
}

/// Pass 1 of [`extract`]: per fixed chunk of cells, the cells with a case, their triangles
/// and used centres; and a bitmap (by edge key) of the crossed edges some triangle uses.
fn find_cases(cubes: &SparseCubes, n: usize, table: &Table) -> (Vec<ChunkCases>, Vec<u64>) {
    let used: Vec<AtomicU64> = (0..(3 * n).div_ceil(64))
        .into_par_iter()
        .map(|_| AtomicU64::new(0))
        .collect();
    let chunks: Vec<ChunkCases> = cubes
        .cells
        .par_chunks(CHUNK)
        .map(|cells| {
            let mut chunk = ChunkCases {
                corners: Vec::with_capacity(cells.len()),
                cases: Vec::with_capacity(cells.len()),
                ..Default::default()
            };
            for_each_case(cubes, n, cells, |idx, mask, bits| {
                let case = table.case(mask, bits);
                chunk.triangles += case.triangles.len();
                chunk.centres += centres_used(case).count_ones() as usize;
                for tri in &case.triangles {
                    for &v in tri.iter().filter(|&&v| v < CENTRE) {
                        let key = edge_key(idx, v);
                        let (word, bit) = (&used[key / 64], 1u64 << (key % 64));
                        if word.load(Ordering::Relaxed) & bit == 0 {
                            word.fetch_or(bit, Ordering::Relaxed);
                        }
                    }
                }
                chunk
                    .corners
                    .push([idx[0], idx[1], idx[2], idx[3]].map(|i| i as u32));
                chunk.cases.push([mask, bits]);
            });
            chunk
        })
        .collect();
    (
        chunks,
        used.into_iter().map(AtomicU64::into_inner).collect(),
    )
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

/// Calls `f(corner indices, corner mask, face bits)` for every cell of `cells` whose eight
/// corners are active vertices (below `n`, which fits a `u32` as the output's indices do) and
/// have a sign change, in order.
pub(crate) fn for_each_case(
    cubes: &SparseCubes,
    n: usize,
    cells: &[[u16; 3]],
    mut f: impl FnMut(&[usize; 8], u8, u8),
) {
    let coords = &cubes.coords[..n];
    let sdf = &cubes.sdf[..n];
    // One monotone cursor per corner column (dx, dy): the targets rise with the cells.
    let mut cursor = [0usize; 4];
    for &cell in cells {
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
        if let Some((mask, bits)) = case_bits(sdf, &idx) {
            f(&idx, mask, bits);
        }
    }
}

/// The corner mask and face bits ([`Table::case`]'s arguments) of the cell whose corners are
/// the vertices `idx` (corner `c` at `(c & 1, c >> 1 & 1, c >> 2)`), or `None` when it has no
/// sign change.
#[inline]
fn case_bits(sdf: &[f32], idx: &[usize; 8]) -> Option<(u8, u8)> {
    let mut mask = 0u8;
    for (c, &i) in idx.iter().enumerate() {
        if sdf[i] < 0.0 {
            mask |= 1 << c;
        }
    }
    if mask == 0 || mask == 0xff {
        return None;
    }
    let mut bits = 0u8;
    let ambiguous = mc_table::ambiguous_faces(mask);
    for (face, fc) in FACE_CORNERS.iter().enumerate() {
        if ambiguous >> face & 1 == 1 && mc_table::inside_joined(fc.map(|c| sdf[idx[c as usize]])) {
            bits |= 1 << face;
        }
    }
    Some((mask, bits))
}

/// The marching-cubes case of the cell whose corners are the vertices `idx`, or `None` when it
/// has no sign change.
#[inline]
fn case_of<'t>(sdf: &[f32], table: &'t Table, idx: &[usize; 8]) -> Option<&'t Case> {
    case_bits(sdf, idx).map(|(mask, bits)| table.case(mask, bits))
}

/// Appends to `out` the triangles that [`extract`] emits for one cell, given the indices in
/// `cubes.coords` of its eight corners (corner `c` at `(c & 1, c >> 1 & 1, c >> 2)`), with
/// the same positions (grid coordinates, deformation applied, rounded to `f32` as in the
/// extracted mesh) and orientation. A cell without a sign change adds nothing.
pub fn cell_triangles(cubes: &SparseCubes, idx: &[usize; 8], out: &mut Vec<[[f64; 3]; 3]>) {
    cell_triangles_at(&mut CellEdgePoints::new(cubes, idx), out);
}

/// [`cell_triangles`] of the cell whose crossing points `edges` holds.
pub(crate) fn cell_triangles_at(edges: &mut CellEdgePoints, out: &mut Vec<[[f64; 3]; 3]>) {
    let Some(case) = case_of(&edges.cubes.sdf, mc_table::table(), edges.idx) else {
        return;
    };
    let mut point = |v: u8| {
        let p = if v < CENTRE {
            edges.get(v)
        } else {
            edges.centre(&case.centres[(v - CENTRE) as usize])
        };
        to_f32(p).map(f64::from)
    };
    for tri in &case.triangles {
        out.push([point(tri[0]), point(tri[1]), point(tri[2])]);
    }
}

/// The crossing points ([`edge_point`]) of one cell's edges, each computed at most once.
pub(crate) struct CellEdgePoints<'c> {
    cubes: &'c SparseCubes,
    idx: &'c [usize; 8],
    points: [Option<[f64; 3]>; 12],
}

impl<'c> CellEdgePoints<'c> {
    /// None computed yet, for the cell with corners `idx`.
    pub(crate) fn new(cubes: &'c SparseCubes, idx: &'c [usize; 8]) -> Self {
        Self {
            cubes,
            idx,
            points: [None; 12],
        }
    }

    /// The crossing point on edge `e`.
    #[inline]
    pub(crate) fn get(&mut self, e: u8) -> [f64; 3] {
        *self.points[e as usize].get_or_insert_with(|| edge_point(self.cubes, self.idx, e))
    }

    /// A centre vertex: the mean of the crossing points of `edges` ([`centre_point`]).
    fn centre(&mut self, edges: &[u8]) -> [f64; 3] {
        mean(edges.iter().map(|&e| self.get(e)), edges.len())
    }
}

/// The centre vertices a case's triangles use, as a bit set over centre numbers.
#[inline]
pub(crate) fn centres_used(case: &Case) -> u32 {
    let mut mask = 0u32;
    for tri in &case.triangles {
        for &v in tri.iter().filter(|&&v| v >= CENTRE) {
            mask |= 1 << (v - CENTRE);
        }
    }
    mask
}

/// Key of cube edge `e` of a cell with corners `idx`: its lower vertex index × 3 + axis.
#[inline]
fn edge_key(idx: &[usize; 8], e: u8) -> usize {
    let (a, _, axis) = EDGES[e as usize];
    idx[a as usize] * 3 + axis as usize
}

/// Position of vertex `i` (grid coordinates plus deformation).
#[inline]
fn position(cubes: &SparseCubes, i: usize) -> [f64; 3] {
    let c = cubes.coords[i];
    let d = cubes.deformation.get(i).copied().unwrap_or([0.0; 3]);
    [
        c[0] as f64 + d[0] as f64,
        c[1] as f64 + d[1] as f64,
        c[2] as f64 + d[2] as f64,
    ]
}

/// Crossing point of the zero level set on cube edge `e` (linear interpolation of φ between
/// the edge's two vertices, which alone decide it).
#[inline]
pub(crate) fn edge_point(cubes: &SparseCubes, idx: &[usize; 8], e: u8) -> [f64; 3] {
    let (a, b, _) = EDGES[e as usize];
    let (ia, ib) = (idx[a as usize], idx[b as usize]);
    let (sa, sb) = (cubes.sdf[ia] as f64, cubes.sdf[ib] as f64);
    let mut w = sa / (sa - sb);
    if !w.is_finite() {
        w = 0.5;
    }
    let w = w.clamp(0.0, 1.0);
    let (pa, pb) = (position(cubes, ia), position(cubes, ib));
    [
        pa[0] + w * (pb[0] - pa[0]),
        pa[1] + w * (pb[1] - pa[1]),
        pa[2] + w * (pb[2] - pa[2]),
    ]
}

/// A centre vertex: the mean of the crossing points of `edges`.
fn centre_point(cubes: &SparseCubes, idx: &[usize; 8], edges: &[u8]) -> [f64; 3] {
    mean(
        edges.iter().map(|&e| edge_point(cubes, idx, e)),
        edges.len(),
    )
}

/// The mean of `count` points, summed in order.
#[inline]
fn mean(points: impl Iterator<Item = [f64; 3]>, count: usize) -> [f64; 3] {
    let mut s = [0.0; 3];
    for p in points {
        s = [s[0] + p[0], s[1] + p[1], s[2] + p[2]];
    }
    let m = count as f64;
    [s[0] / m, s[1] / m, s[2] / m]
}

#[inline]
fn to_f32(p: [f64; 3]) -> [f32; 3] {
    [p[0] as f32, p[1] as f32, p[2] as f32]
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
