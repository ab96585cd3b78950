//! Inside or outside of the watertight output, read from the sparse grid alone: no dense
//! grid, no winding number, no ray cast against the whole mesh.
//!
//! The surface that [`crate::extract()`] emits lies in the active cells (each cell's triangles
//! inside the cell; with deformation, within 0.45 voxel of it). So for a point in grid
//! coordinates:
//!
//! - **Near the surface** (an active cell among the 3×3×3 cells around the point's cell; only
//!   the point's own cell without deformation): take a stored corner `v` of the point's cell,
//!   whose side is the sign of its φ, and count how often the segment from the point to `v`'s
//!   (deformed) position crosses the triangles of those active cells, rebuilt cell by cell
//!   with [`crate::stages::extract::cell_triangles`]. Every triangle that can cross the segment is
//!   among them, so an odd count flips `v`'s side.
//! - **Elsewhere**: cells without a sign change have corners of one sign, and face-adjacent
//!   ones share corners, so a run of such cells along +z has one side. Walk the column to the
//!   first active cell: its lower corner on the column is stored, and its sign is the run's
//!   side. A column without an active cell above the point is outside (the grid border is).
//!   With deformation the surface moves less than 0.45·√3 < 1 voxel from where it is without,
//!   and a point here is at least a voxel away from it, so its side does not change.
//!
//! A segment passing exactly through a triangle's edge or vertex, or lying in its plane, has a
//! parity that its crossings cannot give. That is a set of measure zero for arbitrary points,
//! but not for points rounded to a storage precision: `f16` sample points lie on dyadic planes
//! of the grid, and at 512³ a strict crossing test gave 15–338 of 250k near-surface samples per
//! item (0.05 % over 16 dev meshes) the wrong side (checked by the winding number; on
//! quarter-voxel points of the bundled meshes 1.7 %). So a crossing within a tolerance of a
//! triangle's border is *unsure*, and an unsure segment is replaced by the segment to the next
//! stored corner, or as a last resort to the nearest corner nudged off the grid's planes by
//! 1e-4 voxel. [`crate::products::samples`] takes most sides from the closest face first
//! ([`crate::queries::closest::TriangleIndex::face_side`]) and asks this module only for the rest.

use crate::grid::cubes::SparseCubes;
use crate::grid::{pack, split, test, BrickIndex, BrickSet, Numbered, BRICK};
use crate::stages::extract::cell_triangles;
use crate::vec3::{cross, dot, sub, Vec3};
use rayon::prelude::*;

/// The inside/outside classifier of one item's sparse cubes (module docs).
#[derive(Debug)]
pub struct GridSides<'a> {
    /// The sparse cubes.
    cubes: &'a SparseCubes,
    /// The active cells.
    cells: BrickSet,
    /// The stored vertices, numbered in brick order.
    verts: Numbered,
    /// Index in `cubes.coords` of each numbered vertex.
    vertex_index: Vec<u32>,
    /// Whether any vertex is displaced (then the 3×3×3 neighbourhood is searched).
    deformed: bool,
}

/// Reusable scratch space of one thread's queries.
#[derive(Debug, Default)]
pub struct SidesScratch {
    triangles: Vec<[[f64; 3]; 3]>,
}

/// Sorted, deduplicated packed keys of `coords` in the brick space of resolution `n`.
fn packed(index: &BrickIndex, coords: &[[u16; 3]]) -> Vec<u64> {
    let mut keys: Vec<u64> = coords
        .par_iter()
        .map(|c| pack(index, [c[0] as u32, c[1] as u32, c[2] as u32]))
        .collect();
    keys.par_sort_unstable();
    keys.dedup();
    keys
}

impl<'a> GridSides<'a> {
    /// Builds the classifier (brick sets of the active cells and stored vertices).
    pub fn new(cubes: &'a SparseCubes) -> Self {
        let n = cubes.resolution;
        let index = BrickIndex::for_resolution(n);
        let cells = BrickSet::from_sorted_packed(n, &packed(&index, &cubes.cells));
        let verts = Numbered::new(BrickSet::from_sorted_packed(
            n,
            &packed(&index, &cubes.coords),
        ));
        let mut vertex_index = vec![u32::MAX; verts.len];
        for (i, c) in cubes.coords.iter().enumerate() {
            if let Some(id) = verts.id([c[0] as i64, c[1] as i64, c[2] as i64]) {
                vertex_index[id as usize] = i as u32;
            }
        }
        let deformed = cubes.deformation.iter().any(|d| *d != [0.0; 3]);
        Self {
            cubes,
            cells,
            verts,
            vertex_index,
            deformed,
        }
    }

    /// Whether the point `g` (grid coordinates, voxels) is inside the extracted surface.
    pub fn is_inside(&self, g: Vec3, scratch: &mut SidesScratch) -> bool {
        let n = self.cubes.resolution as f64;
        if !g.iter().all(|&c| (0.0..n).contains(&c)) {
            return false;
        }
        let cell = g.map(|c| c.floor() as i64);
        let reach = if self.deformed { 1 } else { 0 };
        let mut near = false;
        'block: for dz in -reach..=reach {
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    if self
                        .cells
                        .contains([cell[0] + dx, cell[1] + dy, cell[2] + dz])
                    {
                        near = true;
                        break 'block;
                    }
                }
            }
        }
        if near {
            self.local_side(g, cell, reach, scratch)
        } else {
            self.column_side(cell)
        }
    }

    /// Sides of many points (grid coordinates), in parallel; independent of the thread count.
    pub fn inside_batch(&self, points: &[Vec3]) -> Vec<bool> {
        points
            .par_iter()
            .map_init(SidesScratch::default, |s, &g| self.is_inside(g, s))
            .collect()
    }

    /// Index in `cubes.coords` of the stored vertex at `c`.
    #[inline]
    fn vertex(&self, c: [i64; 3]) -> Option<usize> {
        let id = self.verts.id(c)?;
        let i = self.vertex_index[id as usize];
        (i != u32::MAX).then_some(i as usize)
    }

    /// Corner indices of cell `c` when all eight are stored.
    fn corners(&self, c: [i64; 3]) -> Option<[usize; 8]> {
        let mut idx = [0usize; 8];
        for (k, slot) in idx.iter_mut().enumerate() {
            let k = k as i64;
            *slot = self.vertex([c[0] + (k & 1), c[1] + ((k >> 1) & 1), c[2] + (k >> 2)])?;
        }
        Some(idx)
    }

    /// Parity of crossings between `g` and a stored corner of its cell (module docs). The
    /// nearest stored corner is tried first; when its segment meets a triangle too close to
    /// the triangle's border (or lies in its plane) to call, the next corner is tried, and as
    /// a last resort the nearest corner's end is nudged off the grid's planes.
    fn local_side(&self, g: Vec3, cell: [i64; 3], reach: i64, scratch: &mut SidesScratch) -> bool {
        // The stored corners of the cell, nearest to g first (ties to the lower corner number).
        let mut corners = [(0.0f64, 0usize); 8];
        let mut stored = 0;
        for k in 0..8i64 {
            let c = [
                cell[0] + (k & 1),
                cell[1] + ((k >> 1) & 1),
                cell[2] + (k >> 2),
            ];
            if let Some(i) = self.vertex(c) {
                let d: f64 = (0..3).map(|a| (c[a] as f64 - g[a]).powi(2)).sum();
                corners[stored] = (d, i);
                stored += 1;
            }
        }
        if stored == 0 {
            // No stored corner: no active cell shares a vertex with this one.
            return self.column_side(cell);
        }
        let corners = &mut corners[..stored];
        // Stable, so equally near corners keep their corner order.
        corners.sort_by(|a, b| a.0.total_cmp(&b.0));
        scratch.triangles.clear();
        for dz in -reach..=reach {
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    let c = [cell[0] + dx, cell[1] + dy, cell[2] + dz];
                    if self.cells.contains(c) {
                        if let Some(idx) = self.corners(c) {
                            cell_triangles(self.cubes, &idx, &mut scratch.triangles);
                        }
                    }
                }
            }
        }
        // Inside when corner `v` is and the segment to it crosses the surface an even number
        // of times, or when it is not and the number is odd.
        let side = |v: usize, odd: bool| (self.cubes.sdf[v] < 0.0) != odd;
        let triangles = &scratch.triangles;
        for &(_, v) in corners.iter() {
            if let Ok(odd) = crossing_parity(g, position(self.cubes, v), triangles) {
                return side(v, odd);
            }
        }
        // Every corner's segment grazes a triangle: nudge the nearest corner's end by a
        // ten-thousandth of a voxel along directions no grid plane or edge follows. The corner
        // is at least that far from the surface unless its φ is within about 1e-4 of zero.
        // Should every nudge graze too, the first one's count decides, grazes counted as misses.
        let v = corners[0].1;
        let at = position(self.cubes, v);
        let nudged = |k: usize| -> Vec3 { std::array::from_fn(|a| at[a] + 1e-4 * NUDGES[k][a]) };
        let odd = match crossing_parity(g, nudged(0), triangles) {
            Ok(odd) => odd,
            Err(counted) => (1..NUDGES.len())
                .find_map(|k| crossing_parity(g, nudged(k), triangles).ok())
                .unwrap_or(counted),
        };
        side(v, odd)
    }

    /// Side of a cell without a sign change, from the first active cell above it along +z.
    fn column_side(&self, cell: [i64; 3]) -> bool {
        let n = self.cubes.resolution as i64;
        let (x, y) = (cell[0], cell[1]);
        if x < 0 || y < 0 || x >= n || y >= n {
            return false;
        }
        let mut z = cell[2] + 1;
        while z < n {
            let (b, _, bit) = split([x as u32, y as u32, z as u32]);
            match self.cells.mask_at([b[0] as i64, b[1] as i64, b[2] as i64]) {
                None => z = (b[2] as i64 + 1) * BRICK as i64,
                Some(m) => {
                    let end = ((b[2] as i64 + 1) * BRICK as i64).min(n);
                    while z < end {
                        if test(m, (z & 7) as usize, bit) {
                            return self
                                .vertex([x, y, z])
                                .is_some_and(|v| self.cubes.sdf[v] < 0.0);
                        }
                        z += 1;
                    }
                }
            }
        }
        false
    }
}

/// Position of vertex `i`: grid coordinates plus deformation.
#[inline]
fn position(cubes: &SparseCubes, i: usize) -> Vec3 {
    let c = cubes.coords[i];
    let d = cubes.deformation.get(i).copied().unwrap_or([0.0; 3]);
    std::array::from_fn(|a| c[a] as f64 + d[a] as f64)
}

/// Directions to nudge a segment's end along when its crossings cannot be called: unit-ish
/// vectors with irrational ratios of components, so the nudged end lies on no dyadic plane.
const NUDGES: [[f64; 3]; 3] = [
    [0.577_215_664_9, 0.309_016_994_4, 0.751_988_482_6],
    [-0.414_213_562_4, 0.732_050_807_6, 0.540_302_305_9],
    [0.236_067_977_5, -0.645_751_311_1, 0.726_542_528_0],
];

/// The parity of the crossings of the segment `p`–`q` with `triangles`: `Ok` when every
/// crossing can be called, else `Err` with the parity that counts the unsure ones as misses.
fn crossing_parity(p: Vec3, q: Vec3, triangles: &[[[f64; 3]; 3]]) -> Result<bool, bool> {
    let (mut odd, mut sure) = (false, true);
    for t in triangles {
        match segment_crossing(p, q, t) {
            Crossing::Miss => {}
            Crossing::Hit => odd = !odd,
            Crossing::Unsure => sure = false,
        }
    }
    if sure {
        Ok(odd)
    } else {
        Err(odd)
    }
}

/// Tolerance of [`segment_crossing`]'s barycentric and along-segment coordinates: a hit
/// closer than this to a triangle's border (in its own normalised coordinates) is unsure.
const GRAZE: f64 = 1e-9;

/// How a segment meets a triangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Crossing {
    /// Clearly not: outside the triangle or the segment by more than [`GRAZE`].
    Miss,
    /// Clearly through the triangle's interior, between the segment's ends.
    Hit,
    /// Through or along the triangle's border, at an end, or in its plane: the parity of
    /// such a segment cannot be read from its crossings.
    Unsure,
}

/// How the segment `p`–`q` meets triangle `t` (Möller–Trumbore on the segment, with a
/// tolerance band around every border: f16 sample points lie on dyadic planes of the grid, so
/// a segment to a grid corner can pass exactly through an edge two triangles share, which a
/// strict test counts twice or not at all).
#[inline]
fn segment_crossing(p: Vec3, q: Vec3, t: &[[f64; 3]; 3]) -> Crossing {
    let dir = sub(q, p);
    let e1 = sub(t[1], t[0]);
    let e2 = sub(t[2], t[0]);
    let h = cross(dir, e2);
    let det = dot(e1, h);
    if !det.is_finite() {
        return Crossing::Miss;
    }
    let s = sub(p, t[0]);
    let normal = cross(e1, e2);
    let scale = dot(normal, normal).sqrt() * dot(dir, dir).sqrt();
    if det.abs() <= GRAZE * scale {
        // Parallel to the plane: a miss unless the segment lies in it.
        let height = dot(s, normal).abs();
        let area = dot(normal, normal).sqrt();
        let reach = dot(dir, dir).sqrt() + dot(e1, e1).sqrt() + dot(e2, e2).sqrt();
        return if height <= GRAZE * area * reach.max(1.0) {
            Crossing::Unsure
        } else {
            Crossing::Miss
        };
    }
    let inv = 1.0 / det;
    let u = dot(s, h) * inv;
    let qv = cross(s, e1);
    let v = dot(dir, qv) * inv;
    let along = dot(e2, qv) * inv;
    let w = 1.0 - u - v;
    if u < -GRAZE || v < -GRAZE || w < -GRAZE || !(-GRAZE..=1.0 + GRAZE).contains(&along) {
        Crossing::Miss
    } else if u > GRAZE && v > GRAZE && w > GRAZE && along > GRAZE && along < 1.0 - GRAZE {
        Crossing::Hit
    } else {
        Crossing::Unsure
    }
}
