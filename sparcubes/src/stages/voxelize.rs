//! Stage 2: where the surface meets the grid. Two exact rasterisations of every triangle:
//!
//! * **wall cells** — cells whose closed box the triangle touches (separating-axis test,
//!   Akenine-Möller). The flood fill may not pass them, so holes narrower than a cell are
//!   sealed.
//! * **blocked edges** — grid edges the triangle crosses (or touches), found by stabbing the
//!   triangle with the grid lines of each axis. They decide the side of vertices that only
//!   touch wall cells, and which crossings separate inside from outside.

use crate::grid::{split, BrickIndex, BrickMask, BrickSet, BRICK};
use crate::mesh::GridMesh;
use crate::vec3::{cross, dot, sub};
use rayon::prelude::*;

/// Wall cells and blocked edges of a mesh at resolution `n`.
#[derive(Debug, Clone)]
pub struct Voxelization {
    /// Cells touched by the surface.
    pub walls: BrickSet,
    /// Per axis: vertices whose edge towards +axis is crossed or touched by the surface.
    pub blocked: [BrickSet; 3],
}

/// Whether a triangle touches the closed axis-aligned box `center ± half` (separating axis
/// theorem with the 13 axes of Akenine-Möller, "Fast 3D triangle-box overlap testing", 2001).
pub fn triangle_box_overlap(tri: &[[f64; 3]; 3], center: [f64; 3], half: f64) -> bool {
    let Some(centred) = CentredTriangle::unless_boxes_apart(tri, center, half) else {
        return false;
    };
    (0..AXES).all(|k| !centred.separates(k, half))
}

/// A triangle in coordinates centred on a box, as [`triangle_box_overlap`] computes it: the
/// one place its axis tests are written, so that [`CellTest`]'s fallback repeats them bit for
/// bit.
struct CentredTriangle {
    v: [[f64; 3]; 3],
    e: [[f64; 3]; 3],
}

impl CentredTriangle {
    /// The triangle centred on `center`, or `None` when a coordinate axis separates it from the
    /// box `center ± half` (their bounding boxes are apart).
    #[inline]
    fn unless_boxes_apart(tri: &[[f64; 3]; 3], center: [f64; 3], half: f64) -> Option<Self> {
        let v = [
            sub(tri[0], center),
            sub(tri[1], center),
            sub(tri[2], center),
        ];
        for a in 0..3 {
            let lo = v[0][a].min(v[1][a]).min(v[2][a]);
            let hi = v[0][a].max(v[1][a]).max(v[2][a]);
            if lo > half || hi < -half {
                return None;
            }
        }
        let e = [sub(v[1], v[0]), sub(v[2], v[1]), sub(v[0], v[2])];
        Some(Self { v, e })
    }

    /// Whether axis `k` of [`CellTest`]'s order (0: the normal, `1 + 3 * edge + a`: coordinate
    /// axis `a` crossed with edge `edge`) separates the triangle from the box of half size
    /// `half` around the origin.
    #[inline]
    fn separates(&self, k: usize, half: f64) -> bool {
        let v = &self.v;
        if k == 0 {
            let n = cross(self.e[0], self.e[1]);
            let r = half * (n[0].abs() + n[1].abs() + n[2].abs());
            return dot(n, v[0]).abs() > r;
        }
        let mut unit = [0.0; 3];
        unit[(k - 1) % 3] = 1.0;
        let axis = cross(unit, self.e[(k - 1) / 3]);
        let p = [dot(axis, v[0]), dot(axis, v[1]), dot(axis, v[2])];
        let r = half * (axis[0].abs() + axis[1].abs() + axis[2].abs());
        p[0].min(p[1]).min(p[2]) > r || p[0].max(p[1]).max(p[2]) < -r
    }
}

/// [`triangle_box_overlap`] against unit cells for one triangle, with the triangle's side of
/// the test set up once: for each of the 10 axes that are not a coordinate axis (the normal
/// and the 9 edge cross products), the triangle's projection range and the cell's radius, so a
/// cell costs one dot product per axis. Rounding makes these projections differ from the
/// direct test's in the last bits, so on an axis where a cell lies within `margin` of deciding,
/// the direct test's own computation for that axis decides (and the coordinate axes, as the
/// direct test has them): the answer is always the direct test's, bit for bit. A cell is unsure
/// on a few axes at most (a face lying on a cell plane: the normal and the edge axes parallel
/// to it), and only those are redone; a face in a grid-aligned plane never needs them (see
/// [`CellTest::new`]).
pub struct CellTest<'a> {
    tri: &'a [[f64; 3]; 3],
    origin: [f64; 3],
    axis: [[f64; AXES]; 3],
    lo: [f64; AXES],
    hi: [f64; AXES],
    /// Cell radius on the axis plus the margin: beyond it, surely separated.
    outer: [f64; AXES],
    /// Cell radius on the axis minus the margin: within it, surely overlapping.
    inner: [f64; AXES],
}

/// Axes of [`CellTest`]: the normal and the 9 cross products of a coordinate axis with an edge.
const AXES: usize = 10;

impl<'a> CellTest<'a> {
    /// Sets up the test of `tri` against unit cells whose centres lie in the triangle's
    /// bounding box grown by one cell (the candidates [`for_each_touched_cell`] tests).
    pub fn new(tri: &'a [[f64; 3]; 3]) -> Self {
        let origin = tri[0];
        let v = [[0.0; 3], sub(tri[1], origin), sub(tri[2], origin)];
        let e = [v[1], sub(v[2], v[1]), sub(v[0], v[2])];
        let mut axes = [cross(e[0], e[1]); AXES];
        for (k, edge) in e.iter().enumerate() {
            for a in 0..3 {
                let mut unit = [0.0; 3];
                unit[a] = 1.0;
                axes[1 + 3 * k + a] = cross(unit, *edge);
            }
        }
        // Rounding bound, far above the few ulps either computation can be off by: both work
        // on coordinates up to `big` and differences up to `span` (the candidate cells'
        // centres lie within one cell of the triangle's box).
        let (mut big, mut span) = (0.0f64, 0.0f64);
        for a in 0..3 {
            let mn = tri[0][a].min(tri[1][a]).min(tri[2][a]);
            let mx = tri[0][a].max(tri[1][a]).max(tri[2][a]);
            big = big.max(mn.abs()).max(mx.abs());
            span = span.max(mx - mn);
        }
        let (big, span) = (big + 2.0, span + 2.0);
        let margin = 1e-12 * (big + span) * span * span;
        let mut test = CellTest {
            tri,
            origin,
            axis: [[0.0; AXES]; 3],
            lo: [0.0; AXES],
            hi: [0.0; AXES],
            outer: [0.0; AXES],
            inner: [0.0; AXES],
        };
        for (k, axis) in axes.iter().enumerate() {
            let p = [0.0, dot(*axis, v[1]), dot(*axis, v[2])];
            let r = 0.5 * (axis[0].abs() + axis[1].abs() + axis[2].abs());
            for a in 0..3 {
                test.axis[a][k] = axis[a];
            }
            test.lo[k] = p[0].min(p[1]).min(p[2]);
            test.hi[k] = p[0].max(p[1]).max(p[2]);
            test.outer[k] = r + margin;
            test.inner[k] = r - margin;
        }
        // A triangle in a grid-aligned plane (its corners share coordinate `a` exactly, as the
        // flat faces of CAD parts on the grid's outer planes do): the normal and the six edge
        // axes crossed with the other two coordinate axes all point along `a`, their other
        // components exactly zero. On such an axis the direct test projects the triangle to
        // one point `p = fl(w * v_a)` against `r = fl(w / 2)`, and a candidate cell has
        // `|v_a| <= 1/2` exactly (the coordinate axis `a` does not separate it), so rounding,
        // being monotone, keeps `|p| <= r`: never separated, never redone. Only the three
        // in-plane edge normals are left to decide.
        if let Some(a) = (0..3).find(|&a| tri[0][a] == tri[1][a] && tri[1][a] == tri[2][a]) {
            for k in (0..AXES).filter(|&k| k == 0 || (k - 1) % 3 != a) {
                test.outer[k] = f64::INFINITY;
                test.inner[k] = f64::INFINITY;
            }
        }
        test
    }

    /// Whether the triangle touches the closed unit cell `c` (the same answer as
    /// [`triangle_box_overlap`] with its centre and half size 0.5). `c` must lie within one
    /// cell of the triangle's bounding box on every axis, where the coordinate axes never
    /// separate (see [`for_each_touched_cell`]).
    #[inline]
    pub fn touches(&self, c: [i64; 3]) -> bool {
        let center = [c[0] as f64 + 0.5, c[1] as f64 + 0.5, c[2] as f64 + 0.5];
        let d = sub(center, self.origin);
        let (mut separated, mut unsure) = (false, 0u16);
        for k in 0..AXES {
            let s = self.axis[0][k] * d[0] + self.axis[1][k] * d[1] + self.axis[2][k] * d[2];
            let (lo, hi) = (self.lo[k] - s, self.hi[k] - s);
            separated |= (lo > self.outer[k]) | (hi < -self.outer[k]);
            let sure = (lo < self.inner[k]) & (hi > -self.inner[k]);
            unsure |= (!sure as u16) << k;
        }
        if separated {
            return false;
        }
        if unsure == 0 {
            return true;
        }
        // Every axis not redone here is surely not separating, as the direct test would find.
        let Some(centred) = CentredTriangle::unless_boxes_apart(self.tri, center, 0.5) else {
            return false;
        };
        (0..AXES).all(|k| unsure & (1 << k) == 0 || !centred.separates(k, 0.5))
    }
}

/// An inclusive range of integer coordinates per axis, `(lo, hi)`.
pub type Clip = ([i64; 3], [i64; 3]);

/// Calls `f(cell)` for every cell within `clip` whose closed box the triangle touches.
/// Work is proportional to the triangle's projected area on its dominant plane, not to its
/// bounding box volume.
pub fn for_each_touched_cell(tri: &[[f64; 3]; 3], clip: Clip, mut f: impl FnMut([u32; 3])) {
    let mut lo = [0i64; 3];
    let mut hi = [0i64; 3];
    for a in 0..3 {
        let mn = tri[0][a].min(tri[1][a]).min(tri[2][a]);
        let mx = tri[0][a].max(tri[1][a]).max(tri[2][a]);
        lo[a] = (mn.ceil() as i64 - 1).max(clip.0[a]);
        hi[a] = (mx.floor() as i64).min(clip.1[a]);
        if lo[a] > hi[a] {
            return;
        }
    }
    // Every cell of lo..=hi meets the triangle's bounding box (lo = ⌈min⌉ − 1, hi = ⌊max⌋),
    // so the coordinate axes of the separating-axis test never separate it.
    let cell_test = CellTest::new(tri);
    let test = |c: [i64; 3]| cell_test.touches(c);
    let volume = (0..3).map(|a| (hi[a] - lo[a] + 1) as u64).product::<u64>();
    let nrm = cross(sub(tri[1], tri[0]), sub(tri[2], tri[0]));
    let w = (0..3)
        .max_by(|&a, &b| nrm[a].abs().total_cmp(&nrm[b].abs()))
        .unwrap_or(2);
    if volume <= 64 || nrm[w] == 0.0 {
        if nrm[w] == 0.0 && volume > 4096 {
            // A degenerate sliver with a huge box has no area: it separates nothing.
            return;
        }
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    if test([x, y, z]) {
                        f([x as u32, y as u32, z as u32]);
                    }
                }
            }
        }
        return;
    }
    // Walk the columns along the dominant normal axis w; in each column only the few cells
    // around the plane can touch the triangle.
    let (u, v) = ((w + 1) % 3, (w + 2) % 3);
    let d = dot(nrm, tri[0]);
    let plane_w = |pu: f64, pv: f64| (d - nrm[u] * pu - nrm[v] * pv) / nrm[w];
    for iu in lo[u]..=hi[u] {
        for iv in lo[v]..=hi[v] {
            let (fu, fv) = (iu as f64, iv as f64);
            let ws = [
                plane_w(fu, fv),
                plane_w(fu + 1.0, fv),
                plane_w(fu, fv + 1.0),
                plane_w(fu + 1.0, fv + 1.0),
            ];
            let wmin = ws.iter().cloned().fold(f64::INFINITY, f64::min);
            let wmax = ws.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            let a = (wmin.ceil() as i64 - 1).max(lo[w]);
            let b = (wmax.floor() as i64).min(hi[w]);
            for iw in a..=b {
                let mut c = [0i64; 3];
                c[u] = iu;
                c[v] = iv;
                c[w] = iw;
                if test(c) {
                    f([c[0] as u32, c[1] as u32, c[2] as u32]);
                }
            }
        }
    }
}

/// Calls `f(vertex, axis)` for every grid edge (from `vertex` towards +axis, `vertex` within
/// `clip`, edges ending at most at `n`) that the closed triangle crosses or touches. An edge
/// lying in the triangle's plane is not reported (the other axes block around it).
pub fn for_each_crossed_edge(
    tri: &[[f64; 3]; 3],
    n: u32,
    clip: Clip,
    mut f: impl FnMut([u32; 3], usize),
) {
    let nrm = cross(sub(tri[1], tri[0]), sub(tri[2], tri[0]));
    let d = dot(nrm, tri[0]);
    for a in 0..3 {
        if nrm[a] == 0.0 {
            continue;
        }
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        let p = [
            [tri[0][b], tri[0][c]],
            [tri[1][b], tri[1][c]],
            [tri[2][b], tri[2][c]],
        ];
        let bmin = (p[0][0].min(p[1][0]).min(p[2][0]).ceil() as i64).max(clip.0[b]);
        let bmax = (p[0][0].max(p[1][0]).max(p[2][0]).floor() as i64).min(clip.1[b]);
        let cmin = (p[0][1].min(p[1][1]).min(p[2][1]).ceil() as i64).max(clip.0[c]);
        let cmax = (p[0][1].max(p[1][1]).max(p[2][1]).floor() as i64).min(clip.1[c]);
        let edge = |i: usize, j: usize, q: [f64; 2]| {
            (p[j][0] - p[i][0]) * (q[1] - p[i][1]) - (p[j][1] - p[i][1]) * (q[0] - p[i][0])
        };
        for jb in bmin..=bmax {
            for jc in cmin..=cmax {
                let q = [jb as f64, jc as f64];
                let e = [edge(0, 1, q), edge(1, 2, q), edge(2, 0, q)];
                let inside = (e[0] >= 0.0 && e[1] >= 0.0 && e[2] >= 0.0)
                    || (e[0] <= 0.0 && e[1] <= 0.0 && e[2] <= 0.0);
                if !inside {
                    continue;
                }
                let t = (d - nrm[b] * q[0] - nrm[c] * q[1]) / nrm[a];
                if !(0.0..=n as f64).contains(&t) {
                    continue;
                }
                let base = (t.floor() as i64).min(n as i64 - 1);
                let mut v = [0u32; 3];
                v[b] = jb as u32;
                v[c] = jc as u32;
                let lowest = if t == t.floor() && base == t as i64 && base > 0 {
                    base - 1
                } else {
                    base
                };
                for va in lowest.max(clip.0[a])..=base.min(clip.1[a]) {
                    v[a] = va as u32;
                    f(v, a);
                }
            }
        }
    }
}

/// The bricks whose closed box `[8b, 8b + 8]³` the triangle touches: every cell it touches and
/// every edge it crosses (by the edge's lower vertex) lies in one of them.
fn touched_bricks(tri: &[[f64; 3]; 3], index: &BrickIndex, mut f: impl FnMut(usize)) {
    let mut lo = [0i64; 3];
    let mut hi = [0i64; 3];
    for a in 0..3 {
        let mn = tri[0][a].min(tri[1][a]).min(tri[2][a]);
        let mx = tri[0][a].max(tri[1][a]).max(tri[2][a]);
        lo[a] = ((mn / BRICK as f64).floor() as i64 - 1).max(0);
        hi[a] = ((mx / BRICK as f64).floor() as i64).min(index.dims[a] as i64 - 1);
    }
    let half = BRICK as f64 / 2.0;
    for bz in lo[2]..=hi[2] {
        for by in lo[1]..=hi[1] {
            for bx in lo[0]..=hi[0] {
                let center = [
                    bx as f64 * 8.0 + half,
                    by as f64 * 8.0 + half,
                    bz as f64 * 8.0 + half,
                ];
                if triangle_box_overlap(tri, center, half) {
                    f(index.key([bx as u32, by as u32, bz as u32]));
                }
            }
        }
    }
}

/// Rasterises every triangle of `mesh` at resolution `n`. Triangles are first binned to the
/// 8³ bricks they touch; each brick then rasterises its own triangles into local masks, in
/// parallel, so no per-cell list is ever built or sorted. The result does not depend on the
/// thread count.
pub fn voxelize(mesh: &GridMesh, n: u32) -> Voxelization {
    let index = BrickIndex::for_resolution(n);
    let mut pairs: Vec<u64> = (0..mesh.tris.len())
        .into_par_iter()
        .with_min_len(256)
        .fold(Vec::new, |mut out: Vec<u64>, t| {
            touched_bricks(&mesh.tri(t), &index, |key| {
                out.push(((key as u64) << 32) | t as u64)
            });
            out
        })
        .reduce(Vec::new, |mut a, b| {
            a.extend(b);
            a
        });
    pairs.par_sort_unstable();
    let mut runs: Vec<(usize, usize)> = Vec::new();
    for (i, p) in pairs.iter().enumerate() {
        match runs.last_mut() {
            Some(r) if pairs[r.0] >> 32 == p >> 32 => r.1 = i + 1,
            _ => runs.push((i, i + 1)),
        }
    }
    let last_cell = n as i64 - 1;
    let masks: Vec<(u32, [BrickMask; 4])> = runs
        .par_iter()
        .map(|&(start, end)| {
            let key = (pairs[start] >> 32) as u32;
            let b = index.coord(key as usize);
            let base = [b[0] as i64 * 8, b[1] as i64 * 8, b[2] as i64 * 8];
            let top = [base[0] + 7, base[1] + 7, base[2] + 7];
            let cells: Clip = (
                base,
                [
                    top[0].min(last_cell),
                    top[1].min(last_cell),
                    top[2].min(last_cell),
                ],
            );
            let verts: Clip = (base, top);
            let mut m = [[0u64; 8]; 4];
            for p in &pairs[start..end] {
                let tri = mesh.tri((p & 0xFFFF_FFFF) as usize);
                for_each_touched_cell(&tri, cells, |c| {
                    let (_, w, bit) = split(c);
                    m[0][w] |= 1u64 << bit;
                });
                for_each_crossed_edge(&tri, n, verts, |v, axis| {
                    let (_, w, bit) = split(v);
                    m[1 + axis][w] |= 1u64 << bit;
                });
            }
            (key, m)
        })
        .collect();
    let set =
        |k: usize| BrickSet::from_masks(n, masks.iter().map(|(key, m)| (*key, m[k])).collect());
    Voxelization {
        walls: set(0),
        blocked: [set(1), set(2), set(3)],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_overlap_is_closed_and_exact() {
        let tri = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]];
        assert!(
            triangle_box_overlap(&tri, [0.5, 0.5, 0.5], 0.5),
            "touching the top face"
        );
        assert!(!triangle_box_overlap(&tri, [0.5, 0.5, 0.49], 0.5));
        let diag = [[0.0, 0.0, 0.0], [3.0, 3.0, 0.0], [0.0, 0.0, 3.0]];
        assert!(triangle_box_overlap(&diag, [1.5, 1.5, 1.5], 0.5));
        assert!(!triangle_box_overlap(&diag, [2.5, 0.5, 0.5], 0.5));
    }

    #[test]
    fn cell_test_answers_as_the_direct_test() {
        // Triangles with corners on grid planes, lines and vertices (where the exact answer
        // turns on the last bit), slivers, and large ones far from the origin.
        let tris = [
            [[1.0, 1.0, 1.0], [3.0, 1.0, 1.0], [1.0, 3.0, 1.0]],
            [[2.0, 0.5, 0.0], [2.0, 4.5, 3.0], [2.0, 0.5, 4.0]],
            [[1.3, 2.2, 3.7], [9.1, 4.4, 2.2], [4.5, 11.2, 8.9]],
            [[0.1, 0.1, 0.1], [5.0, 5.0, 5.0], [5.0, 5.0, 5.000001]],
            [[1000.25, 3.0, 7.0], [1003.0, 3.0, 8.5], [1001.0, 9.0, 7.0]],
            [[0.0, 0.0, 3.0], [6.0, 6.0, 3.0], [0.0, 6.0, 3.0]],
            [[2.0, 2.0, 2.0], [2.0, 2.0, 2.0], [4.0, 4.0, 4.0]],
        ];
        let touching: usize = tris
            .iter()
            .map(|tri| answers_as_the_direct_test(tri)[1])
            .sum();
        assert!(touching > 100);
    }

    /// Asserts that [`CellTest::touches`] answers as [`triangle_box_overlap`] on every
    /// candidate cell of `tri` (its bounding box grown by one cell); returns how many cells
    /// it does not and does touch.
    fn answers_as_the_direct_test(tri: &[[f64; 3]; 3]) -> [usize; 2] {
        let test = CellTest::new(tri);
        let mut lo = [0i64; 3];
        let mut hi = [0i64; 3];
        for a in 0..3 {
            let mn = tri[0][a].min(tri[1][a]).min(tri[2][a]);
            let mx = tri[0][a].max(tri[1][a]).max(tri[2][a]);
            lo[a] = mn.ceil() as i64 - 1;
            hi[a] = mx.floor() as i64;
        }
        let mut counts = [0; 2];
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    let c = [x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5];
                    let direct = triangle_box_overlap(tri, c, 0.5);
                    assert_eq!(test.touches([x, y, z]), direct, "{tri:?} cell {x} {y} {z}");
                    counts[direct as usize] += 1;
                }
            }
        }
        counts
    }

    #[test]
    fn cell_test_answers_as_the_direct_test_on_random_and_grid_aligned_triangles() {
        // A small xorshift generator: the test needs reproducible draws, not quality.
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let (mut mixed, mut touching, mut cells) = (0, 0, 0);
        for i in 0..3000 {
            // Corners on grid vertices, edges, half and quarter cells, or anywhere; a third of
            // the triangles lie in a grid plane or a hair off it, and some share, repeat or nearly
            // repeat corners.
            let coord = |draw: u64, snap: u64| {
                let r = (draw % 1_000_000) as f64 / 1_000_000.0 * 9.0 + 1.0;
                match snap {
                    0 => r.round(),
                    1 => (r * 2.0).round() / 2.0,
                    2 => (r * 4.0).round() / 4.0,
                    _ => r,
                }
            };
            let snap = next() % 4;
            let mut tri = [[0.0; 3]; 3];
            for corner in tri.iter_mut() {
                for c in corner.iter_mut() {
                    *c = coord(next(), snap);
                }
            }
            match i % 8 {
                0 | 1 | 5 => {
                    let a = (next() % 3) as usize;
                    let plane = coord(next(), 0);
                    for corner in tri.iter_mut() {
                        corner[a] = plane;
                    }
                    if i % 8 == 5 {
                        // Nearly in the plane: decided within the fast test's margin.
                        tri[2][a] += 1e-9;
                    }
                }
                4 => {
                    // A sliver: two corners a hair apart.
                    tri[2] = tri[1];
                    tri[2][(next() % 3) as usize] += 1e-7;
                }
                2 => {
                    // Two coordinates shared: the triangle lies on a grid line's plane pair.
                    let a = (next() % 3) as usize;
                    tri[1][a] = tri[0][a];
                    tri[2][(a + 1) % 3] = tri[0][(a + 1) % 3];
                }
                3 => tri[2] = tri[1],
                _ => {}
            }
            let [apart, touched] = answers_as_the_direct_test(&tri);
            touching += touched;
            cells += apart + touched;
            mixed += (apart > 0 && touched > 0) as usize;
        }
        assert!(
            touching > 10_000 && cells > 2 * touching,
            "{touching} of {cells}"
        );
        assert!(mixed > 1000, "triangles with cells on both sides: {mixed}");
    }

    #[test]
    fn touched_cells_match_brute_force() {
        let tris = [
            [[1.3, 2.2, 3.7], [9.1, 4.4, 2.2], [4.5, 11.2, 8.9]],
            [[2.0, 2.0, 2.0], [12.0, 2.0, 2.0], [2.0, 12.0, 2.5]],
            [[5.5, 1.2, 1.2], [5.7, 13.0, 2.0], [5.6, 2.0, 13.1]],
        ];
        for tri in &tris {
            let mut fast = Vec::new();
            for_each_touched_cell(tri, ([0; 3], [15; 3]), |c| fast.push(c));
            fast.sort();
            let mut slow = Vec::new();
            for z in 0..16u32 {
                for y in 0..16u32 {
                    for x in 0..16u32 {
                        let c = [x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5];
                        if triangle_box_overlap(tri, c, 0.5) {
                            slow.push([x, y, z]);
                        }
                    }
                }
            }
            slow.sort();
            assert_eq!(fast, slow);
        }
    }

    #[test]
    fn crossed_edges_match_segment_tests() {
        let tri = [[1.3, 2.2, 3.7], [9.1, 4.4, 2.2], [4.5, 11.2, 8.9]];
        let mut got = Vec::new();
        for_each_crossed_edge(&tri, 16, ([0; 3], [16; 3]), |v, a| got.push((v, a)));
        got.sort();
        got.dedup();
        // Every reported edge's segment meets the triangle's plane inside the triangle, and the
        // count equals the number of grid lines through the projected triangle per axis.
        let nrm = cross(sub(tri[1], tri[0]), sub(tri[2], tri[0]));
        for &(v, a) in &got {
            let p0 = [v[0] as f64, v[1] as f64, v[2] as f64];
            let mut p1 = p0;
            p1[a] += 1.0;
            let s0 = dot(nrm, sub(p0, tri[0]));
            let s1 = dot(nrm, sub(p1, tri[0]));
            assert!(
                s0 * s1 <= 0.0,
                "edge {v:?} axis {a} does not cross the plane"
            );
        }
        assert!(got.len() > 50);
    }
}
