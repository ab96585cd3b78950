//! The generalised winding number of a triangle soup: a robust inside test that needs neither a
//! closed nor a manifold mesh.
//!
//! The winding number of a query point q is the signed solid angle the surface subtends at q,
//! over 4π (Jacobson, Kavan and Sorkine-Hornung, "Robust Inside-Outside Segmentation using
//! Generalized Winding Numbers", 2013): 1 inside a closed outward-oriented surface, 0 outside,
//! k inside k nested ones, and close to those values where the surface has small holes. Each
//! triangle contributes its exact solid angle (Van Oosterom and Strackee, 1983).
//!
//! Evaluation is hierarchical, after Barill, Dickson, Schmidt, Levin and Jacobson, "Fast Winding
//! Numbers for Soups and Clouds" (SIGGRAPH 2018): a bounding hierarchy over the triangles
//! carries, per node, the area-weighted centre of its triangles, a radius around it, and the
//! Taylor coefficients of the node's solid-angle integral about that centre up to second order
//! (the area vector and its first and second moments, exact integrals over the triangles). A
//! node whose centre is more than [`BETA`] radii from q contributes its expansion; nearer nodes
//! are opened, and leaves are summed exactly.
//!
//! The hierarchy is a radix tree over the triangles sorted by the Morton code of their
//! centroids (ranges split where the codes' highest differing bit turns on): a sort and one
//! pass, a few times cheaper to build than a surface-area-heuristic BVH for what these
//! queries need — nodes that are spatially tight.
//!
//! Everything is double precision and every sum runs in a fixed order, so a query's result does
//! not depend on the thread count.

use crate::mesh::GridMesh;
use crate::vec3::{cross, dot, sub};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Far-field criterion: a node is replaced by its expansion when the query is more than
/// `BETA` times its radius from its centre. Barill et al. use 2; 1.5 opens about half as many
/// nodes for queries near the surface, and the largest error measured against β = 4 at points
/// a voxel from the surface of three large dev-corpus meshes was 0.01 (0.003 with β = 2),
/// far below the margin the verdicts need (`crate::stages::inside` decides at 0.25 and 0.75).
pub const BETA: f64 = 1.5;

/// Most triangles per leaf.
const LEAF_TRIANGLES: u32 = 8;

/// A node's moments about its centre, as built (and shifted from child to parent).
#[derive(Debug, Clone, Copy, Default)]
struct Moments {
    /// Area-weighted centre of the node's triangles.
    center: [f64; 3],
    /// Every point of the node's triangles lies within this distance of `center`.
    radius: f64,
    /// Total area.
    area: f64,
    /// Σ area vector (area × unit normal).
    n: [f64; 3],
    /// `m[i][j]` = Σ ∫ nᵢ (x − c)ⱼ dA.
    m: [[f64; 3]; 3],
    /// `p[i][s]` = Σ ∫ nᵢ (x − c)ⱼ (x − c)ₖ dA for the pair s = (j, k) of [`PAIRS`].
    p: [[f64; 6]; 3],
}

/// The six index pairs (j ≤ k) of a symmetric 3×3 matrix.
const PAIRS: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

/// The ten monomials dₐd_bd_c (a ≤ b ≤ c) of a symmetric 3-tensor contracted with d³.
const TRIPLES: [(usize, usize, usize); 10] = [
    (0, 0, 0),
    (1, 1, 1),
    (2, 2, 2),
    (0, 0, 1),
    (0, 0, 2),
    (0, 1, 1),
    (1, 1, 2),
    (0, 2, 2),
    (1, 2, 2),
    (0, 1, 2),
];

/// A node's expansion, contracted for evaluation: with d = centre − q and r = |d|, its solid
/// angle is d·n/r³ + (tr M)/r³ − 3 dᵀMd/r⁵ + ½(−3 v·d/r⁵ + 15 T(d)/r⁷).
#[derive(Debug, Clone, Copy, Default)]
struct Expansion {
    /// Centre.
    center: [f64; 3],
    /// (β · radius)²: queries farther than that use the expansion.
    far2: f64,
    /// Σ area vector.
    n: [f64; 3],
    /// tr M.
    trace: f64,
    /// dᵀMd coefficients of d₀², d₁², d₂², d₀d₁, d₀d₂, d₁d₂.
    quad: [f64; 6],
    /// vₖ = 2 Σᵢ pᵢᵢₖ + Σⱼ pₖⱼⱼ.
    v: [f64; 3],
    /// Σ pᵢⱼₖ dᵢdⱼdₖ coefficients, in the order of [`TRIPLES`].
    cubic: [f64; 10],
}

/// [`PAIRS`] index of the pair (j, k), either order.
const PAIR_OF: [[usize; 3]; 3] = [[0, 3, 4], [3, 1, 5], [4, 5, 2]];

/// [`TRIPLES`] index of the sorted triple (i, j, k), any order: a table, so contracting a
/// node's moments is a few hundred flops rather than a search per term (it was most of the
/// tree's build time).
const TRIPLE_OF: [[[usize; 3]; 3]; 3] = triple_table();

const fn triple_table() -> [[[usize; 3]; 3]; 3] {
    let mut table = [[[0; 3]; 3]; 3];
    let mut i = 0;
    while i < 3 {
        let mut j = 0;
        while j < 3 {
            let mut k = 0;
            while k < 3 {
                // Sort (i, j, k) and find it in TRIPLES.
                let (mut a, mut b, mut c) = (i, j, k);
                if a > b {
                    (a, b) = (b, a);
                }
                if b > c {
                    (b, c) = (c, b);
                }
                if a > b {
                    (a, b) = (b, a);
                }
                let mut t = 0;
                while t < TRIPLES.len() {
                    if TRIPLES[t].0 == a && TRIPLES[t].1 == b && TRIPLES[t].2 == c {
                        table[i][j][k] = t;
                    }
                    t += 1;
                }
                k += 1;
            }
            j += 1;
        }
        i += 1;
    }
    table
}

impl Moments {
    /// The contracted form of these moments.
    fn expansion(&self) -> Expansion {
        let full = |i: usize, j: usize, k: usize| -> f64 { self.p[i][PAIR_OF[j][k]] };
        let m = &self.m;
        let mut cubic = [0.0; 10];
        for i in 0..3 {
            for j in 0..3 {
                for k in 0..3 {
                    cubic[TRIPLE_OF[i][j][k]] += full(i, j, k);
                }
            }
        }
        Expansion {
            center: self.center,
            far2: (BETA * self.radius).powi(2),
            n: self.n,
            trace: m[0][0] + m[1][1] + m[2][2],
            quad: [
                m[0][0],
                m[1][1],
                m[2][2],
                m[0][1] + m[1][0],
                m[0][2] + m[2][0],
                m[1][2] + m[2][1],
            ],
            v: std::array::from_fn(|k| {
                2.0 * (0..3).map(|i| full(i, i, k)).sum::<f64>()
                    + (0..3).map(|j| full(k, j, j)).sum::<f64>()
            }),
            cubic,
        }
    }
}

impl Expansion {
    /// The node's solid angle at `q` from its second-order expansion (valid far from it).
    /// The integrand (x − q)·n/|x − q|³ = g(x)·n is expanded about the centre c, with
    /// d = c − q: g = d/r³, ∂ⱼgᵢ = δᵢⱼ/r³ − 3dᵢdⱼ/r⁵,
    /// ∂ⱼ∂ₖgᵢ = −3(δᵢⱼdₖ + δᵢₖdⱼ + δⱼₖdᵢ)/r⁵ + 15dᵢdⱼdₖ/r⁷.
    #[inline]
    fn solid_angle(&self, d: [f64; 3], r2: f64) -> f64 {
        let r = r2.sqrt();
        let inv3 = 1.0 / (r2 * r);
        let inv5 = inv3 / r2;
        let inv7 = inv5 / r2;
        let [x, y, z] = d;
        let q = &self.quad;
        let dmd =
            q[0] * x * x + q[1] * y * y + q[2] * z * z + q[3] * x * y + q[4] * x * z + q[5] * y * z;
        let c = &self.cubic;
        let ddd = c[0] * x * x * x
            + c[1] * y * y * y
            + c[2] * z * z * z
            + c[3] * x * x * y
            + c[4] * x * x * z
            + c[5] * x * y * y
            + c[6] * y * y * z
            + c[7] * x * z * z
            + c[8] * y * z * z
            + c[9] * x * y * z;
        (dot(d, self.n) + self.trace) * inv3 - 3.0 * dmd * inv5
            + 0.5 * (-3.0 * dot(self.v, d) * inv5 + 15.0 * ddd * inv7)
    }
}

/// A node of the tree: children or a range of triangles.
#[derive(Debug, Clone, Copy)]
enum Kind {
    /// Children's node numbers.
    Inner(u32, u32),
    /// `pieces[start..start + count]`.
    Leaf(u32, u32),
}

/// A mesh prepared for fast winding-number queries.
#[derive(Debug, Clone)]
pub struct WindingTree {
    /// The mesh's triangles cut into pieces no longer than the piece length, sorted leaf by
    /// leaf.
    pieces: Vec<[[f64; 3]; 3]>,
    /// Node structure; the root is node 0.
    kinds: Vec<Kind>,
    /// Node expansions, parallel to `kinds`.
    expansions: Vec<Expansion>,
}

/// The exact solid angle of triangle `t` seen from `q`, signed (positive when the triangle's
/// front, counter-clockwise side faces away from q), Van Oosterom and Strackee's formula.
#[inline]
pub fn solid_angle(t: &[[f64; 3]; 3], q: [f64; 3]) -> f64 {
    let a = sub(t[0], q);
    let b = sub(t[1], q);
    let c = sub(t[2], q);
    let (la, lb, lc) = (dot(a, a).sqrt(), dot(b, b).sqrt(), dot(c, c).sqrt());
    let num = dot(a, cross(b, c));
    let den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
    2.0 * num.atan2(den)
}

/// Moments of one triangle about its own centroid.
fn triangle_moments(t: &[[f64; 3]; 3]) -> Moments {
    let av = cross(sub(t[1], t[0]), sub(t[2], t[0]));
    let n = [0.5 * av[0], 0.5 * av[1], 0.5 * av[2]];
    let center: [f64; 3] = std::array::from_fn(|a| (t[0][a] + t[1][a] + t[2][a]) / 3.0);
    let u: [[f64; 3]; 3] = std::array::from_fn(|v| sub(t[v], center));
    // ∫ (x − c)(x − c)ᵀ dA over a triangle = A/12 · (Σ uᵥuᵥᵀ + (Σ uᵥ)(Σ uᵥ)ᵀ), and Σ uᵥ = 0
    // about the centroid; times the unit normal that is the area vector over 12.
    let mut p = [[0.0; 6]; 3];
    for (s, &(j, k)) in PAIRS.iter().enumerate() {
        let second = (u[0][j] * u[0][k] + u[1][j] * u[1][k] + u[2][j] * u[2][k]) / 12.0;
        for i in 0..3 {
            p[i][s] = n[i] * second;
        }
    }
    Moments {
        center,
        radius: u.iter().map(|v| dot(*v, *v).sqrt()).fold(0.0, f64::max),
        area: dot(n, n).sqrt(),
        n,
        m: [[0.0; 3]; 3],
        p,
    }
}

/// Combines moments into one set about their area-weighted centre (their plain mean when
/// they have no area).
fn combine(parts: &[Moments]) -> Moments {
    let area: f64 = parts.iter().map(|p| p.area).sum();
    let center: [f64; 3] = std::array::from_fn(|a| {
        if area > 0.0 {
            parts.iter().map(|e| e.center[a] * e.area).sum::<f64>() / area
        } else {
            parts.iter().map(|e| e.center[a]).sum::<f64>() / parts.len() as f64
        }
    });
    let mut out = Moments {
        center,
        area,
        ..Moments::default()
    };
    for e in parts {
        // Shift by δ = c_part − c: (x − c) = (x − c_part) + δ.
        let d = sub(e.center, center);
        out.radius = out.radius.max(dot(d, d).sqrt() + e.radius);
        for i in 0..3 {
            out.n[i] += e.n[i];
            for j in 0..3 {
                out.m[i][j] += e.m[i][j] + e.n[i] * d[j];
            }
            for (s, &(j, k)) in PAIRS.iter().enumerate() {
                out.p[i][s] +=
                    e.p[i][s] + e.m[i][j] * d[k] + e.m[i][k] * d[j] + e.n[i] * d[j] * d[k];
            }
        }
    }
    out
}

/// Cuts triangle `t` into pieces whose edges are at most `max_edge` long by halving the
/// longest edge (each half keeps the orientation); the pieces' solid angles add up to the
/// triangle's. `stack` is scratch space, reused between triangles.
fn cut(
    t: [[f64; 3]; 3],
    max_edge: f64,
    stack: &mut Vec<[[f64; 3]; 3]>,
    out: &mut Vec<[[f64; 3]; 3]>,
) {
    let limit = max_edge * max_edge;
    stack.clear();
    stack.push(t);
    while let Some(t) = stack.pop() {
        let len2 = |i: usize| {
            let d = sub(t[(i + 1) % 3], t[i]);
            dot(d, d)
        };
        let k = (0..3)
            .max_by(|&i, &j| len2(i).total_cmp(&len2(j)))
            .unwrap_or(0);
        if len2(k) <= limit {
            out.push(t);
            continue;
        }
        let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
        let m: [f64; 3] = std::array::from_fn(|i| 0.5 * (a[i] + b[i]));
        stack.push([m, b, c]);
        stack.push([a, m, c]);
    }
}

/// Triangles per task when cutting: large enough that a task's scratch and output vectors
/// are allocated rarely.
const CUT_CHUNK: usize = 4096;

/// Every triangle of `mesh` cut by [`cut`], in triangle order.
fn cut_all(mesh: &GridMesh, max_edge: f64) -> Vec<[[f64; 3]; 3]> {
    let chunks: Vec<Vec<[[f64; 3]; 3]>> = (0..mesh.tris.len().div_ceil(CUT_CHUNK))
        .into_par_iter()
        .map(|c| {
            let range = c * CUT_CHUNK..((c + 1) * CUT_CHUNK).min(mesh.tris.len());
            let mut out = Vec::with_capacity(2 * range.len());
            let mut stack = Vec::new();
            for t in range {
                cut(mesh.tri(t), max_edge, &mut stack, &mut out);
            }
            out
        })
        .collect();
    chunks.concat()
}

/// Pieces sorted by the Morton code of their centroid (ties by their order in `pieces`), with
/// the sorted codes: spatially close pieces end up next to each other.
fn morton_order(pieces: Vec<[[f64; 3]; 3]>) -> (Vec<[[f64; 3]; 3]>, Vec<u64>) {
    let centroid = |t: &[[f64; 3]; 3]| -> [f64; 3] {
        std::array::from_fn(|k| (t[0][k] + t[1][k] + t[2][k]) / 3.0)
    };
    // Bounds of the centroids: min and max are exact, so the parallel reduction gives the
    // same bounds whatever the thread count.
    let (lo, hi) = pieces
        .par_iter()
        .map(|t| {
            let c = centroid(t);
            (c, c)
        })
        .reduce(
            || ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
            |(alo, ahi), (blo, bhi)| {
                (
                    std::array::from_fn(|a| alo[a].min(blo[a])),
                    std::array::from_fn(|a| ahi[a].max(bhi[a])),
                )
            },
        );
    let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
    let top = ((1u64 << crate::grid::morton::BITS) - 1) as f64;
    let scale = if extent > 0.0 { top / extent } else { 0.0 };
    let mut keyed: Vec<(u64, u32)> = pieces
        .par_iter()
        .enumerate()
        .map(|(i, t)| {
            let c = centroid(t);
            let q = |a: usize| ((c[a] - lo[a]) * scale).clamp(0.0, top) as u64;
            (crate::grid::morton::code([q(0), q(1), q(2)]), i as u32)
        })
        .collect();
    keyed.par_sort_unstable();
    let sorted = keyed.par_iter().map(|&(_, i)| pieces[i as usize]).collect();
    let codes = keyed.par_iter().map(|&(k, _)| k).collect();
    (sorted, codes)
}

impl WindingTree {
    /// Builds the tree over every triangle of `mesh` (grid coordinates), cut into pieces no
    /// longer than `piece` voxels: a long sliver would otherwise make every node holding it
    /// as large as itself, and force exact sums of it (and of its neighbours) on every query
    /// near it. Zero-area triangles subtend no solid angle and change nothing.
    pub fn new(mesh: &GridMesh, piece: f64) -> Self {
        let pieces = cut_all(mesh, piece);
        let (pieces, codes) = morton_order(pieces);
        let kinds = split_ranges(&codes);
        // The leaves' moments in parallel, then the inner nodes' from the last node back (a
        // child's number is larger than its parent's): the same sums in the same order.
        let mut moments: Vec<Moments> = kinds
            .par_iter()
            .map_init(
                || Vec::with_capacity(LEAF_TRIANGLES as usize),
                |leaf, kind| match *kind {
                    Kind::Inner(..) => Moments::default(),
                    Kind::Leaf(start, count) => {
                        leaf.clear();
                        leaf.extend(
                            pieces[start as usize..(start + count) as usize]
                                .iter()
                                .map(triangle_moments),
                        );
                        combine(leaf)
                    }
                },
            )
            .collect();
        for id in (0..kinds.len()).rev() {
            if let Kind::Inner(l, r) = kinds[id] {
                moments[id] = combine(&[moments[l as usize], moments[r as usize]]);
            }
        }
        let expansions = moments.par_iter().map(Moments::expansion).collect();
        Self {
            pieces,
            kinds,
            expansions,
        }
    }

    /// The winding number at `q` (grid coordinates): the solid angle the surface subtends
    /// there over 4π. `stack` is scratch space, reused between queries.
    pub fn winding_number_with(&self, q: [f64; 3], stack: &mut Vec<u32>) -> f64 {
        if self.kinds.is_empty() {
            return 0.0;
        }
        let mut total = 0.0;
        stack.clear();
        stack.push(0);
        while let Some(id) = stack.pop() {
            let e = &self.expansions[id as usize];
            let d = sub(e.center, q);
            let r2 = dot(d, d);
            if r2 > e.far2 {
                total += e.solid_angle(d, r2);
                continue;
            }
            match self.kinds[id as usize] {
                Kind::Inner(left, right) => {
                    stack.push(right);
                    stack.push(left);
                }
                Kind::Leaf(start, count) => {
                    for t in &self.pieces[start as usize..(start + count) as usize] {
                        total += solid_angle(t, q);
                    }
                }
            }
        }
        total / (4.0 * PI)
    }

    /// The winding number at `q` (grid coordinates).
    pub fn winding_number(&self, q: [f64; 3]) -> f64 {
        self.winding_number_with(q, &mut Vec::with_capacity(64))
    }
}

/// A range still to be made a node: (first, end, its parent and whether it is the parent's
/// right child).
type PendingRange = (u32, u32, Option<(usize, bool)>);

/// The node structure over Morton-sorted `codes`, top down in pre-order (a child's number is
/// larger than its parent's): a range is split where the highest bit in which its first and
/// last codes differ turns on (the halves lie in separate octree cells), or in the middle when
/// all its codes are equal; ranges of at most [`LEAF_TRIANGLES`] are leaves.
fn split_ranges(codes: &[u64]) -> Vec<Kind> {
    let mut kinds = Vec::with_capacity(codes.len() / 2 + 1);
    if codes.is_empty() {
        return kinds;
    }
    let mut stack: Vec<PendingRange> = vec![(0, codes.len() as u32, None)];
    while let Some((first, end, parent)) = stack.pop() {
        let id = kinds.len() as u32;
        if let Some((p, right)) = parent {
            if let Kind::Inner(l, r) = &mut kinds[p] {
                *(if right { r } else { l }) = id;
            }
        }
        if end - first <= LEAF_TRIANGLES {
            kinds.push(Kind::Leaf(first, end - first));
            continue;
        }
        let (a, b) = (codes[first as usize], codes[end as usize - 1]);
        let mid = if a == b {
            (first + end) / 2
        } else {
            let bit = 63 - (a ^ b).leading_zeros();
            let range = &codes[first as usize..end as usize];
            first + range.partition_point(|&c| (c >> bit) & 1 == 0) as u32
        };
        kinds.push(Kind::Inner(0, 0));
        stack.push((mid, end, Some((id as usize, true))));
        stack.push((first, mid, Some((id as usize, false))));
    }
    kinds
}

/// A [`WindingTree`] built on first use, so conversions that never ask (no enclosed region,
/// no sealed vertex) do not pay for it.
#[derive(Debug)]
pub struct LazyWindingTree<'a> {
    mesh: &'a GridMesh,
    piece: f64,
    tree: std::sync::OnceLock<WindingTree>,
}

impl<'a> LazyWindingTree<'a> {
    /// A tree over `mesh` with pieces of at most `piece` voxels, not built yet.
    pub fn new(mesh: &'a GridMesh, piece: f64) -> Self {
        Self {
            mesh,
            piece,
            tree: std::sync::OnceLock::new(),
        }
    }

    /// The tree, built now if it was not.
    pub fn get(&self) -> &WindingTree {
        self.tree
            .get_or_init(|| WindingTree::new(self.mesh, self.piece))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes;
    use crate::TriMesh;

    fn grid_mesh(m: &TriMesh) -> GridMesh {
        GridMesh {
            verts: m
                .positions
                .iter()
                .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
                .collect(),
            tris: m.triangles.clone(),
        }
    }

    /// The exact sum over every triangle, without the hierarchy.
    fn brute_force(m: &GridMesh, q: [f64; 3]) -> f64 {
        (0..m.tris.len())
            .map(|t| solid_angle(&m.tri(t), q))
            .sum::<f64>()
            / (4.0 * PI)
    }

    #[test]
    fn one_inside_a_closed_surface_zero_outside() {
        let m = grid_mesh(&shapes::sphere([0.0; 3], 10.0, 32));
        let tree = WindingTree::new(&m, 4.0);
        // The expansions with β = 1.5 are good to 1–2 hundredths (see `BETA`).
        let close = |w: f64, want: f64| (w - want).abs() < 2e-2;
        for q in [[1.0, 2.0, -3.0], [9.5, 0.0, 0.0], [0.0, -9.6, 0.5]] {
            let w = tree.winding_number(q);
            assert!(close(w, 1.0), "{w} at {q:?}");
        }
        for q in [[10.5, 0.0, 0.0], [40.0, -30.0, 7.0]] {
            let w = tree.winding_number(q);
            assert!(close(w, 0.0), "{w} at {q:?}");
        }
        let flipped = grid_mesh(&shapes::flipped(&shapes::sphere([0.0; 3], 10.0, 32)));
        let w = WindingTree::new(&flipped, 4.0).winding_number([0.5; 3]);
        assert!(close(w, -1.0), "{w}");
    }

    #[test]
    fn nested_surfaces_add_up_and_an_open_box_is_fractional() {
        let nested = grid_mesh(&shapes::merge(&[
            shapes::cuboid([-10.0; 3], [10.0; 3], &[]),
            shapes::sphere([0.0; 3], 5.0, 24),
        ]));
        let tree = WindingTree::new(&nested, 4.0);
        for (q, want) in [([0.0; 3], 2.0), ([8.0, 0.0, 0.0], 1.0)] {
            let w = tree.winding_number(q);
            assert!((w - want).abs() < 2e-2, "{w} at {q:?}");
        }
        // A box missing its top: the centre sees five of six faces, 5/6.
        let open = grid_mesh(&shapes::cuboid([-10.0; 3], [10.0; 3], &[5]));
        let w = WindingTree::new(&open, 4.0).winding_number([0.0; 3]);
        assert!((w - 5.0 / 6.0).abs() < 1e-2, "{w}");
    }

    #[test]
    fn hierarchy_matches_the_exact_sum() {
        let m = grid_mesh(&shapes::merge(&[
            shapes::torus([0.0; 3], 10.0, 3.0, 48),
            shapes::cube_with_hole([-4.0; 3], [4.0; 3], 2.0),
            shapes::quad(-20.0, -20.0, 20.0, 20.0, 6.0),
        ]));
        let tree = WindingTree::new(&m, 4.0);
        let mut worst: f64 = 0.0;
        for i in 0..400 {
            let f = i as f64;
            let q = [
                (f * 0.731).sin() * 25.0,
                (f * 1.377).cos() * 25.0,
                (f * 0.419).sin() * 15.0,
            ];
            worst = worst.max((tree.winding_number(q) - brute_force(&m, q)).abs());
        }
        assert!(worst < 2e-2, "largest error {worst}");
    }

    #[test]
    fn expansion_error_falls_with_the_cube_of_the_distance() {
        // Second order: the error of a node's expansion falls as r⁻⁵ against a leading term
        // of r⁻², i.e. by 2⁵ per doubling of the distance.
        let tris = [
            [[0.0, 0.0, 0.0], [1.0, 0.1, 0.2], [0.3, 1.0, -0.1]],
            [[0.5, -0.2, 0.4], [1.2, 0.6, 0.1], [0.1, 0.4, 0.9]],
            [[-0.3, 0.2, 0.1], [0.2, -0.5, 0.3], [0.4, 0.3, -0.6]],
        ];
        let parts: Vec<Moments> = tris.iter().map(triangle_moments).collect();
        let e = combine(&parts).expansion();
        let error = |dist: f64| {
            let q = [
                e.center[0] + dist * 0.6,
                e.center[1] - dist * 0.48,
                e.center[2] + dist * 0.64,
            ];
            let exact: f64 = tris.iter().map(|t| solid_angle(t, q)).sum();
            let d = sub(e.center, q);
            (e.solid_angle(d, dot(d, d)) - exact).abs()
        };
        for dist in [4.0, 8.0] {
            let ratio = error(dist) / error(2.0 * dist);
            assert!((24.0..40.0).contains(&ratio), "ratio {ratio} at {dist}");
        }
    }

    #[test]
    fn same_value_whatever_the_thread_count() {
        let m = grid_mesh(&shapes::torus([0.0; 3], 10.0, 3.0, 48));
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool")
                .install(|| WindingTree::new(&m, 4.0).winding_number([10.2, 0.3, 0.1]))
        };
        assert_eq!(run(1).to_bits(), run(2).to_bits());
    }
}
