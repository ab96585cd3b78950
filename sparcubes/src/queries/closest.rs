//! Exact closest-point queries on a triangle mesh: for a batch of points, the closest point of
//! the mesh, its distance and the triangle it lies on.
//!
//! The tree is a binary BVH over the triangles sorted by the Morton code of their centroids,
//! split where the highest differing code bit changes (a linear BVH); the query is a
//! nearest-first traversal: children are visited nearer box first and a subtree is skipped
//! once its box is not nearer than the best triangle found. An obvhs tree (PLOC, as the
//! renderer uses) was measured first: on the marching-cubes surface of a cube its node boxes
//! overlapped so much that queries were 20–130× slower, and it built 3–7× slower
//! (`examples/closest_bench.rs` with `CUBE=1`). Batches are sorted along a Morton curve and
//! cut into fixed chunks; inside a
//! chunk each query starts from the previous query's triangle as an upper bound, which prunes
//! most of the tree for neighbouring queries.
//!
//! A subtree is skipped as soon as its box is not nearer than the best triangle so far (not
//! only when it is farther): on the large coplanar regions of CAD meshes and marching-cubes
//! surfaces many overlapping boxes lie at exactly the best distance, and visiting them made
//! queries hundreds of times slower. Among equally near triangles the answer is therefore the
//! first one the search meets.
//!
//! Each node also bounds its triangles by an oriented box (axes: the normalised sum of their
//! area vectors and two tangents; the bound is the root of the summed squared gaps along the
//! three axes, taken with the axis-aligned box's bound by `max`, both being lower bounds), and
//! each triangle by its plane. Why: a query at distance d from a nearly flat part visits every
//! leaf whose box reaches into its ball; with a box slack s beyond the surface (2–3 voxels on a
//! tilted part) that is a cap of radius √(2ds), hundreds of triangles for far points, while the
//! oriented box's slack is only the patch's thickness along its normal. On a 964k-triangle
//! output with 250k volume queries (`examples/samples_bench.rs`) the oriented boxes took a
//! volume query from 289 node visits and 367 triangle tests to 106 and 61 (CPU 4.0 s → 1.6 s),
//! a near query from 75 and 71 to 45 and 21. A single slab along the normal, combined with the
//! box by `max` instead of jointly, had given about 5 %; best-first order (a heap) visited
//! only 6 % fewer nodes than this depth-first order seeded by the previous query, and was
//! slower. Leaves of 8 triangles were about 10 % faster than 4.
//!
//! The binary tree is then collapsed into a 4-wide one: each node holds its four children's
//! boxes and oriented boxes side by side (`[axis][lane]`, `f32`), and the four bounds are
//! computed at once in 4-lane `f32` arithmetic (SSE `subps`/`mulps`/`maxps`); the children
//! nearer than the best are pushed farthest first. The stored bounds are exact or rounded
//! outward; the query's own `f32` rounding is absorbed by a margin subtracted from every gap
//! and a relative shrink of the sum, so they stay lower bounds and the answers are the same
//! numbers (the final point–triangle distance is `f64`). On the 964k-triangle output above,
//! one thread: near queries 0.68 → 0.54 s, volume queries 1.23 → 0.88 s. The bounds are squared
//! in `f32`: exact for coordinates below 10¹⁸ in magnitude (grid coordinates are below 10⁴).
//!
//! Determinism: the tree is built single-threaded and the chunks (and so each query's starting
//! triangle) are fixed, so results do not depend on the thread count.

use crate::mesh::triangle::closest_point_on_triangle;
use crate::mesh::TriMesh;
use crate::vec3::{add, cross, dist2, dot, scale, sub};
use rayon::prelude::*;

/// Queries per chunk of a batch (fixed, so results never depend on the thread count).
const CHUNK: usize = 512;

/// The closest point of a mesh to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosestPoint {
    /// The closest point on the mesh.
    pub point: [f64; 3],
    /// Euclidean distance from the query to `point`.
    pub distance: f64,
    /// Index of the triangle (in the mesh's `triangles`) that `point` lies on; among equally
    /// near triangles, the first one the search meets.
    pub triangle: u32,
}

/// A node of the flattened tree: a box, an oriented box, and either two children or a run of
/// triangles.
#[derive(Debug, Clone, Copy)]
struct Node {
    /// Box minimum.
    lo: [f32; 3],
    /// Box maximum.
    hi: [f32; 3],
    /// Inner node: index of the first child (the second follows it). Leaf: first entry of
    /// `TriangleIndex::order`.
    first: u32,
    /// Number of triangles of a leaf; 0 for an inner node.
    count: u32,
    /// Axes of the oriented box, rows of a matrix whose norm is below 1: the normalised sum
    /// of the triangles' area vectors and two tangent directions (see [`frame`]).
    frame: [[f32; 3]; 3],
    /// Smallest `frame[k] · x` over the node's triangles (rounded down).
    near: [f32; 3],
    /// Largest `frame[k] · x` over the node's triangles (rounded up).
    far: [f32; 3],
}

/// A BVH over the triangles of a mesh for exact closest-point queries (see the module docs).
#[derive(Debug, Clone)]
pub struct TriangleIndex {
    /// The 4-wide nodes; the root is node 0 (none for an empty mesh).
    wides: Vec<Wide>,
    /// Triangle indices in leaf order.
    order: Vec<u32>,
    /// Corners of `order[i]`, in leaf order (contiguous per leaf).
    corners: Vec<[[f64; 3]; 3]>,
    /// Unit normal of `order[i]` shortened by one part in 10⁶ (zero for a degenerate
    /// triangle): its distance along it to the first corner never exceeds the distance to
    /// the triangle, so a triangle whose plane is not nearer than the best is skipped.
    normals: Vec<[f32; 3]>,
    /// Position in `order` of each original triangle (the inverse permutation).
    slots: Vec<u32>,
}

impl TriangleIndex {
    /// Builds the tree over every triangle of `mesh` (indices must be in range; a mesh without
    /// triangles gives an index that answers `None`).
    pub fn new(mesh: &TriMesh) -> Self {
        if mesh.triangles.is_empty() {
            return Self {
                wides: Vec::new(),
                order: Vec::new(),
                corners: Vec::new(),
                normals: Vec::new(),
                slots: Vec::new(),
            };
        }
        let centroids: Vec<[f64; 3]> = mesh
            .triangles
            .par_iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
                std::array::from_fn(|k| (a[k] as f64 + b[k] as f64 + c[k] as f64) / 3.0)
            })
            .collect();
        let keyed = morton_keys(&centroids);
        drop(centroids);
        let (keys, order): (Vec<u64>, Vec<u32>) = keyed.into_iter().unzip();
        // Triangles of a leaf are `order[first..first + count]`; their corners are stored in
        // that order so that the build and the queries read them front to back.
        let corners: Vec<[[f64; 3]; 3]> = order
            .par_iter()
            .map(|&t| mesh.triangles[t as usize].map(|i| mesh.positions[i as usize].map(f64::from)))
            .collect();
        let normals = corners
            .par_iter()
            .map(|c| plane_normal(area_vector(c)))
            .collect();
        let nodes = morton_tree(mesh, &order, &keys, &corners);
        let mut slots = vec![u32::MAX; mesh.triangles.len()];
        for (s, &t) in order.iter().enumerate() {
            slots[t as usize] = s as u32;
        }
        let wides = collapse(&nodes);
        Self {
            wides,
            order,
            corners,
            normals,
            slots,
        }
    }

    /// Number of triangles indexed.
    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// Whether no triangle is indexed.
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// The closest point of the mesh to `q`, or `None` for an empty mesh.
    pub fn closest(&self, q: [f64; 3]) -> Option<ClosestPoint> {
        let mut stack = Vec::with_capacity(64);
        self.closest_from(q, None, f64::INFINITY, &mut stack)
    }

    /// The closest points of the mesh to every query, in query order, computed in parallel
    /// (empty when the mesh has no triangle). The result does not depend on the thread count.
    pub fn closest_batch(&self, queries: &[[f64; 3]]) -> Vec<ClosestPoint> {
        self.closest_batch_within(queries, f64::INFINITY)
    }

    /// As [`Self::closest_batch`], but only triangles nearer than `radius` are looked for: a
    /// query with none gets `triangle == u32::MAX` and a NaN distance. Far queries end early
    /// (their search prunes every box not nearer than `radius`), so a band of queries near
    /// the surface costs what its near part costs.
    pub fn closest_batch_within(&self, queries: &[[f64; 3]], radius: f64) -> Vec<ClosestPoint> {
        if self.is_empty() {
            return Vec::new();
        }
        let bound = radius * radius;
        let none = ClosestPoint {
            point: [f64::NAN; 3],
            distance: f64::NAN,
            triangle: u32::MAX,
        };
        let order = morton_order(queries);
        let mut out = vec![none; queries.len()];
        let results: Vec<Vec<ClosestPoint>> = order
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut stack = Vec::with_capacity(64);
                let mut hint = None;
                chunk
                    .iter()
                    .map(|&i| {
                        let c = self
                            .closest_from(queries[i as usize], hint, bound, &mut stack)
                            .unwrap_or(none);
                        if c.triangle != u32::MAX {
                            hint = Some(c.triangle);
                        }
                        c
                    })
                    .collect()
            })
            .collect();
        for (chunk, res) in order.chunks(CHUNK).zip(results) {
            for (&i, c) in chunk.iter().zip(res) {
                out[i as usize] = c;
            }
        }
        out
    }

    /// Nearest-first search from the root among the triangles nearer than `bound` (squared;
    /// infinite for all), with the triangle `hint` (original index) as the first candidate
    /// when given. `None` for an empty index or when no triangle is nearer than `bound`.
    fn closest_from(
        &self,
        q: [f64; 3],
        hint: Option<u32>,
        bound: f64,
        stack: &mut Vec<Entry>,
    ) -> Option<ClosestPoint> {
        if self.wides.is_empty() {
            return None;
        }
        let mut best = (bound, u32::MAX, q);
        if let Some(t) = hint.and_then(|t| self.slot_of(t)) {
            let p = closest_point_on_triangle(q, &self.corners[t]);
            let d2 = dist2(q, p);
            if d2 < best.0 {
                best = (d2, self.order[t], p);
            }
        }
        let query = WideQuery::new(q);
        stack.clear();
        stack.push(Entry {
            first: 0,
            count: 0,
            bound: 0.0,
        });
        while let Some(entry) = stack.pop() {
            if entry.bound >= best.0 {
                continue;
            }
            if entry.count > 0 {
                let start = entry.first as usize;
                for s in start..start + entry.count as usize {
                    let corners = &self.corners[s];
                    let gap = dot(self.normals[s].map(f64::from), sub(q, corners[0]));
                    if gap * gap >= best.0 {
                        continue;
                    }
                    let p = closest_point_on_triangle(q, corners);
                    let d2 = dist2(q, p);
                    let t = self.order[s];
                    if d2 < best.0 {
                        best = (d2, t, p);
                    }
                }
                continue;
            }
            let node = &self.wides[entry.first as usize];
            let bounds = node.dist2(&query);
            // Push the children nearer than the best, farthest first, so that the nearest is
            // visited first (a child whose bound is not below the best is never pushed).
            let mut lanes = [0usize; 4];
            let mut live = 0;
            for (lane, &b) in bounds.iter().enumerate() {
                if b < best.0 {
                    // Insertion by decreasing bound.
                    let mut k = live;
                    while k > 0 && bounds[lanes[k - 1]] < b {
                        lanes[k] = lanes[k - 1];
                        k -= 1;
                    }
                    lanes[k] = lane;
                    live += 1;
                }
            }
            for &lane in &lanes[..live] {
                stack.push(Entry {
                    first: node.child[lane],
                    count: node.count[lane],
                    bound: bounds[lane],
                });
            }
        }
        (best.1 != u32::MAX).then(|| ClosestPoint {
            point: best.2,
            distance: best.0.sqrt(),
            triangle: best.1,
        })
    }

    /// The side of `q` read from its closest triangle (`c`, this index's answer for `q`) when
    /// that is exact: the closest point lies strictly inside the triangle's face (every
    /// sub-triangle of its projection above 10⁻⁷ of the area) and `q` is clear of its plane
    /// (by more than 10⁻⁹ of its largest coordinate, plus 10⁻⁹). Then the open segment from
    /// the closest point to `q` meets no other part of the mesh (that part would be nearer),
    /// so for a closed mesh with outward-facing triangles `q` is inside exactly when it lies
    /// behind the face. `None` otherwise (the closest point on an edge or a corner, or `q` on
    /// the plane): the caller asks another test.
    pub fn face_side(&self, q: [f64; 3], c: &ClosestPoint) -> Option<bool> {
        let [a, b, k] = self.corners[self.slot_of(c.triangle)?];
        let n = cross(sub(b, a), sub(k, a));
        let nn = dot(n, n);
        if !(nn > 0.0 && nn.is_finite()) {
            return None;
        }
        let d = dot(sub(q, a), n);
        let big = q.iter().fold(1.0f64, |m, x| m.max(x.abs()));
        let clear = d.abs() > 1e-9 * big * nn.sqrt();
        if !clear {
            return None;
        }
        let p = sub(q, scale(n, d / nn));
        let margin = 1e-7 * nn;
        let inside_edge = |u: [f64; 3], v: [f64; 3]| dot(cross(sub(v, u), sub(p, u)), n) > margin;
        (inside_edge(a, b) && inside_edge(b, k) && inside_edge(k, a)).then_some(d < 0.0)
    }

    /// Position in leaf order of original triangle `t`.
    #[inline]
    fn slot_of(&self, t: u32) -> Option<usize> {
        match self.slots.get(t as usize) {
            Some(&s) if s != u32::MAX => Some(s as usize),
            _ => None,
        }
    }
}

/// An entry of the traversal stack: a 4-wide node (`count` 0, `first` its index) or a leaf's
/// run of triangles, with a lower bound of its squared distance to the query.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Entry {
    first: u32,
    count: u32,
    bound: f64,
}

/// Four children of a node of the 4-wide tree, their bounds side by side (`[axis][lane]`) so
/// that the four are tested at once in 4-lane `f32` arithmetic. An unused lane has infinite
/// bounds (never visited).
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
struct Wide {
    lo: [[f32; 4]; 3],
    hi: [[f32; 4]; 3],
    /// `frame[row][axis][lane]`: the oriented boxes' axes (see [`frame`]).
    frame: [[[f32; 4]; 3]; 3],
    near: [[f32; 4]; 3],
    far: [[f32; 4]; 3],
    /// Inner child: index of its 4-wide node. Leaf: first entry of `TriangleIndex::order`.
    child: [u32; 4],
    /// Number of triangles of a leaf child; 0 for an inner child or an unused lane.
    count: [u32; 4],
}

/// A query point prepared for [`Wide::dist2`].
struct WideQuery {
    q: [f32; 3],
    /// Subtracted from every gap: covers the rounding of the query to `f32` (at most 2⁻²⁴ of
    /// its largest coordinate) and of the oriented box's `f32` dot product (at most about
    /// 7·2⁻²⁴ of it), so the `f32` gaps never exceed the exact ones.
    margin: f32,
}

impl WideQuery {
    fn new(q: [f64; 3]) -> Self {
        let big = q.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        Self {
            q: q.map(|c| c as f32),
            margin: (big * f64::from(2.0f32.powi(-20))) as f32,
        }
    }
}

/// Shrinks an `f32` bound by far more than the relative rounding of its handful of `f32`
/// operations (about 10·2⁻²⁴), so that it stays a lower bound of the exact squared distance.
const SHRINK: f64 = 1.0 - 1e-5;

/// `a` if it is larger than `b`, else `b` (one `maxps` lane; the bounds are never NaN for
/// finite queries).
#[inline(always)]
fn larger(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

impl Wide {
    /// A node whose four lanes are unused.
    const UNUSED: Wide = Wide {
        lo: [[f32::INFINITY; 4]; 3],
        hi: [[f32::INFINITY; 4]; 3],
        frame: [[[0.0; 4]; 3]; 3],
        near: [[f32::INFINITY; 4]; 3],
        far: [[f32::INFINITY; 4]; 3],
        child: [u32::MAX; 4],
        count: [0; 4],
    };

    /// Puts the bounds of binary node `node` in `lane`, with its child or triangles.
    fn set(&mut self, lane: usize, node: &Node, child: u32, count: u32) {
        for a in 0..3 {
            self.lo[a][lane] = node.lo[a];
            self.hi[a][lane] = node.hi[a];
            self.near[a][lane] = node.near[a];
            self.far[a][lane] = node.far[a];
            for row in 0..3 {
                self.frame[row][a][lane] = node.frame[row][a];
            }
        }
        self.child[lane] = child;
        self.count[lane] = count;
    }

    /// Lower bounds of the squared distances from the query to the four children: the larger
    /// of the squared distances to the box and to the oriented box, computed in `f32` lanes,
    /// each gap lessened by the query's margin and the sum shrunk by [`SHRINK`].
    #[inline]
    fn dist2(&self, w: &WideQuery) -> [f64; 4] {
        let mut s = [0.0f32; 4];
        let mut o = [0.0f32; 4];
        for a in 0..3 {
            for l in 0..4 {
                let d = larger(self.lo[a][l] - w.q[a], w.q[a] - self.hi[a][l]) - w.margin;
                let d = larger(d, 0.0);
                s[l] += d * d;
            }
        }
        for row in 0..3 {
            let f = &self.frame[row];
            for l in 0..4 {
                let t = f[0][l] * w.q[0] + f[1][l] * w.q[1] + f[2][l] * w.q[2];
                let g = larger(self.near[row][l] - t, t - self.far[row][l]) - w.margin;
                let g = larger(g, 0.0);
                o[l] += g * g;
            }
        }
        std::array::from_fn(|l| f64::from(larger(s[l], o[l])) * SHRINK)
    }
}

/// The 4-wide tree of a binary tree (`nodes[0]` the root): each 4-wide node takes a binary
/// node's two children and opens the inner one with the largest box surface until it has four
/// (or only leaves). Node 0 is the root.
fn collapse(nodes: &[Node]) -> Vec<Wide> {
    let mut wides = Vec::with_capacity(nodes.len() / 3 + 1);
    wides.push(Wide::UNUSED);
    let root = &nodes[0];
    if root.count > 0 {
        wides[0].set(0, root, root.first, root.count);
    } else {
        fill(nodes, 0, 0, &mut wides);
    }
    wides
}

/// Fills 4-wide node `wide` with the children of binary inner node `id` (recursively).
fn fill(nodes: &[Node], id: usize, wide: usize, wides: &mut Vec<Wide>) {
    let first = nodes[id].first as usize;
    let mut kids = [first, first + 1, 0, 0];
    let mut len = 2;
    while len < 4 {
        let widest = (0..len)
            .filter(|&k| nodes[kids[k]].count == 0)
            .max_by(|&a, &b| surface(&nodes[kids[a]]).total_cmp(&surface(&nodes[kids[b]])));
        let Some(k) = widest else { break };
        let open = nodes[kids[k]].first as usize;
        // Keep the children in tree (Morton) order.
        kids.copy_within(k + 1..len, k + 2);
        kids[k] = open;
        kids[k + 1] = open + 1;
        len += 1;
    }
    for (lane, &k) in kids[..len].iter().enumerate() {
        let node = &nodes[k];
        if node.count > 0 {
            wides[wide].set(lane, node, node.first, node.count);
        } else {
            let child = wides.len();
            wides.push(Wide::UNUSED);
            wides[wide].set(lane, node, child as u32, 0);
            fill(nodes, k, child, wides);
        }
    }
}

/// Half the surface area of a node's box.
fn surface(node: &Node) -> f64 {
    let e: [f64; 3] = std::array::from_fn(|a| f64::from(node.hi[a]) - f64::from(node.lo[a]));
    e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
}

/// Triangles per leaf of [`morton_tree`].
const LEAF: usize = 8;

/// A tree over triangles sorted by the Morton code of their centroids (`order`, `keys`, and
/// their `corners` in that order): each node splits its run where the highest differing code
/// bit changes (halfway when all codes are equal), leaves hold up to [`LEAF`] triangles,
/// children are adjacent. Returns the nodes.
fn morton_tree(
    mesh: &TriMesh,
    order: &[u32],
    keys: &[u64],
    corners: &[[[f64; 3]; 3]],
) -> Vec<Node> {
    let blank = Node {
        lo: [0.0; 3],
        hi: [0.0; 3],
        first: 0,
        count: 0,
        frame: [[0.0; 3]; 3],
        near: [0.0; 3],
        far: [0.0; 3],
    };
    let mut build = Build {
        mesh,
        order,
        keys,
        corners,
        nodes: Vec::with_capacity(2 * order.len() / LEAF + 1),
        points: Vec::with_capacity(order.len()),
    };
    build.nodes.push(blank);
    build.node(0, 0, order.len());
    build.nodes
}

/// Triangles up to which a node's oriented box is measured on its triangles' corners; above,
/// on the corners of its children's boxes (looser, but such large nodes are rarely flat).
const EXACT_FRAME: usize = 512;

/// The state of [`morton_tree`]'s recursion.
struct Build<'a> {
    mesh: &'a TriMesh,
    order: &'a [u32],
    keys: &'a [u64],
    corners: &'a [[[f64; 3]; 3]],
    nodes: Vec<Node>,
    /// The distinct corners of each leaf, leaf after leaf: the corners of a node's triangles
    /// are a run of them (a leaf's 8 triangles have about 3 times fewer distinct corners than
    /// corners, and the oriented extents of every node up to [`EXACT_FRAME`] triangles are
    /// measured on them).
    points: Vec<[f64; 3]>,
}

impl Build<'_> {
    /// Fills node `id` with the run `start..end` of the sorted triangles (recursively);
    /// returns the run's area vector (sum of the triangles' edge cross products) and its run
    /// of `points`.
    fn node(&mut self, id: usize, start: usize, end: usize) -> ([f64; 3], usize, usize) {
        if end - start <= LEAF {
            return self.leaf(id, start, end);
        }
        let (a, b) = (self.keys[start], self.keys[end - 1]);
        let mid = if a == b {
            (start + end) / 2
        } else {
            let bit = 63 - (a ^ b).leading_zeros();
            let split = start + self.keys[start..end].partition_point(|k| (k >> bit) & 1 == 0);
            split.clamp(start + 1, end - 1)
        };
        let left = self.nodes.len();
        let blank = self.nodes[0];
        self.nodes.push(blank);
        self.nodes.push(blank);
        let (area_l, from, _) = self.node(left, start, mid);
        let (area_r, _, to) = self.node(left + 1, mid, end);
        let area = add(area_l, area_r);
        let frame = frame(area);
        let (l, r) = (self.nodes[left], self.nodes[left + 1]);
        let (near, far) = if end - start <= EXACT_FRAME {
            extents(&frame, self.points[from..to].iter().copied())
        } else {
            extents(&frame, box_corners(&l).chain(box_corners(&r)))
        };
        self.nodes[id] = Node {
            lo: std::array::from_fn(|k| l.lo[k].min(r.lo[k])),
            hi: std::array::from_fn(|k| l.hi[k].max(r.hi[k])),
            first: left as u32,
            count: 0,
            frame,
            near,
            far,
        };
        (area, from, to)
    }

    /// Fills leaf `id` with the triangles `start..end` (see [`Build::node`]).
    fn leaf(&mut self, id: usize, start: usize, end: usize) -> ([f64; 3], usize, usize) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let mut area = [0.0; 3];
        let from = self.points.len();
        let mut seen = [u32::MAX; 3 * LEAF];
        let mut distinct = 0;
        for s in start..end {
            let c = &self.corners[s];
            for p in c {
                for a in 0..3 {
                    lo[a] = lo[a].min(p[a]);
                    hi[a] = hi[a].max(p[a]);
                }
            }
            area = add(area, area_vector(c));
            let vertices = self.mesh.triangles[self.order[s] as usize];
            for (v, p) in vertices.iter().zip(c) {
                if !seen[..distinct].contains(v) {
                    seen[distinct] = *v;
                    distinct += 1;
                    self.points.push(*p);
                }
            }
        }
        let frame = frame(area);
        let to = self.points.len();
        let (near, far) = extents(&frame, self.points[from..to].iter().copied());
        // The corners are `f32` values, so their bounds are exact in `f32`.
        self.nodes[id] = Node {
            lo: lo.map(|v| v as f32),
            hi: hi.map(|v| v as f32),
            first: start as u32,
            count: (end - start) as u32,
            frame,
            near,
            far,
        };
        (area, from, to)
    }
}

/// Twice the area vector of a triangle (the cross product of two edges), in `f64`.
fn area_vector(c: &[[f64; 3]; 3]) -> [f64; 3] {
    let [a, b, c] = *c;
    cross(sub(b, a), sub(c, a))
}

/// The plane normal of an area vector: its direction shortened by one part in 10⁶ so that,
/// rounded to `f32`, its length stays at most 1 (then a gap along it never exceeds a distance);
/// zero for a zero or non-finite vector.
fn plane_normal(area: [f64; 3]) -> [f32; 3] {
    let len = dot(area, area).sqrt();
    if !(len > 0.0 && len.is_finite()) {
        return [0.0; 3];
    }
    area.map(|c| (c / len * (1.0 - 1e-6)) as f32)
}

/// The axes of a node's oriented box: the direction of `area` (the z axis when it is zero or
/// not finite) and two tangent directions, orthonormal in `f64`, shortened by one part in 10⁵
/// and rounded to `f32`. The rounding moves each entry by at most 6·10⁻⁸ of its value, so the
/// matrix of the three rows keeps a norm below 1: the root of the summed squared gaps along
/// them never exceeds a distance.
fn frame(area: [f64; 3]) -> [[f32; 3]; 3] {
    let len = dot(area, area).sqrt();
    let n = if len > 0.0 && len.is_finite() {
        area.map(|c| c / len)
    } else {
        [0.0, 0.0, 1.0]
    };
    // The world axis least aligned with `n` gives the first tangent.
    let least = (0..3)
        .min_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs()))
        .unwrap_or(0);
    let mut e = [0.0; 3];
    e[least] = 1.0;
    let t = cross(n, e);
    let t = t.map(|c| c / dot(t, t).sqrt());
    let u = cross(n, t);
    [n, t, u].map(|v| v.map(|c| (c * (1.0 - 1e-5)) as f32))
}

/// The eight corners of a node's box.
fn box_corners(node: &Node) -> impl Iterator<Item = [f64; 3]> {
    let (lo, hi) = (node.lo, node.hi);
    (0..8).map(move |c| {
        std::array::from_fn(|a| f64::from(if c >> a & 1 == 0 { lo[a] } else { hi[a] }))
    })
}

/// `[min, max]` of `frame[k] · x` over `points`, rounded outward to `f32`.
fn extents(frame: &[[f32; 3]; 3], points: impl Iterator<Item = [f64; 3]>) -> ([f32; 3], [f32; 3]) {
    let axes = frame.map(|f| f.map(f64::from));
    let mut near = [f64::INFINITY; 3];
    let mut far = [f64::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            let d = dot(axes[k], p);
            near[k] = near[k].min(d);
            far[k] = far[k].max(d);
        }
    }
    let mut lo = [0.0; 3];
    let mut hi = [0.0; 3];
    for k in 0..3 {
        (lo[k], hi[k]) = outward(near[k], far[k]);
    }
    (lo, hi)
}

/// `[near, far]` rounded outward to `f32` (one unit in the last place beyond the nearest).
fn outward(near: f64, far: f64) -> (f32, f32) {
    ((near as f32).next_down(), (far as f32).next_up())
}

/// (Morton code, index) of every point over the points' bounding box, sorted (21 bits per
/// axis; non-finite coordinates count as the box minimum).
fn morton_keys(points: &[[f64; 3]]) -> Vec<(u64, u32)> {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for q in points {
        for a in 0..3 {
            if q[a].is_finite() {
                lo[a] = lo[a].min(q[a]);
                hi[a] = hi[a].max(q[a]);
            }
        }
    }
    let cells = ((1u64 << crate::grid::morton::BITS) - 1) as f64;
    let scale: [f64; 3] = std::array::from_fn(|a| {
        let e = hi[a] - lo[a];
        if e > 0.0 && e.is_finite() {
            cells / e
        } else {
            0.0
        }
    });
    let mut keyed: Vec<(u64, u32)> = points
        .par_iter()
        .enumerate()
        .map(|(i, q)| {
            let cell: [u64; 3] = std::array::from_fn(|a| {
                let v = (q[a] - lo[a]) * scale[a];
                if v.is_finite() {
                    v.clamp(0.0, cells) as u64
                } else {
                    0
                }
            });
            (crate::grid::morton::code(cell), i as u32)
        })
        .collect();
    keyed.par_sort_unstable();
    keyed
}

/// Query numbers sorted along a Morton curve over the queries' bounding box (ties by number).
fn morton_order(queries: &[[f64; 3]]) -> Vec<u32> {
    morton_keys(queries).into_iter().map(|(_, i)| i).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::products::samples::rng::uniforms;
    use crate::shapes::{merge, quad, sphere, torus};

    /// Brute force: the smallest squared distance over every triangle.
    fn brute(mesh: &TriMesh, q: [f64; 3]) -> f64 {
        (0..mesh.triangles.len())
            .map(|t| dist2(q, closest_point_on_triangle(q, &mesh.triangle(t))))
            .fold(f64::INFINITY, f64::min)
    }

    fn test_mesh() -> TriMesh {
        merge(&[
            sphere([0.0, 0.0, 0.0], 0.5, 24),
            torus([0.3, -0.2, 0.1], 0.4, 0.1, 20),
            quad(-0.9, -0.9, 0.2, 0.4, 0.55),
        ])
    }

    #[test]
    fn batch_matches_brute_force_exactly() {
        let mesh = test_mesh();
        let index = TriangleIndex::new(&mesh);
        assert_eq!(index.len(), mesh.triangles.len());
        let queries: Vec<[f64; 3]> = (0..2000)
            .map(|i| {
                let u = uniforms(7, 1, i);
                // Near and far points, some exactly on a vertex.
                let s = if i % 3 == 0 { 3.0 } else { 1.3 };
                [s * (u[0] - 0.5), s * (u[1] - 0.5), s * (u[2] - 0.5)]
            })
            .chain(mesh.positions.iter().take(50).map(|p| p.map(|c| c as f64)))
            .collect();
        let got = index.closest_batch(&queries);
        for (q, c) in queries.iter().zip(&got) {
            let d = brute(&mesh, *q).sqrt();
            // Bit for bit: no bound may skip the nearest triangle, so the minimum is the same
            // number whatever the tree's bounds (the sample columns depend on it).
            assert_eq!(c.distance, d, "{q:?}: {c:?}");
            // The reported triangle is one of the nearest, and the point lies on it.
            let own = closest_point_on_triangle(*q, &mesh.triangle(c.triangle as usize));
            assert!((dist2(*q, own).sqrt() - d).abs() <= 1e-9, "{q:?}");
            assert!((dist2(*q, c.point).sqrt() - c.distance).abs() < 1e-12);
        }
    }

    #[test]
    fn a_bounded_batch_answers_the_near_queries_exactly_and_no_far_one() {
        let mesh = test_mesh();
        let index = TriangleIndex::new(&mesh);
        let queries: Vec<[f64; 3]> = (0..3000)
            .map(|i| uniforms(3, 5, i).map(|u| 3.0 * u - 1.5))
            .collect();
        let radius = 0.3;
        let bounded = index.closest_batch_within(&queries, radius);
        let (mut near, mut far) = (0, 0);
        for (q, c) in queries.iter().zip(&bounded) {
            let d = brute(&mesh, *q).sqrt();
            if d < radius {
                near += 1;
                assert_eq!(c.distance, d, "{q:?}: {c:?}");
            } else {
                far += 1;
                assert_eq!(c.triangle, u32::MAX, "{q:?} at {d}: {c:?}");
            }
        }
        assert!(near > 100 && far > 100, "{near} near, {far} far");
    }

    #[test]
    fn same_answers_one_by_one_and_in_parallel() {
        let mesh = test_mesh();
        let index = TriangleIndex::new(&mesh);
        let queries: Vec<[f64; 3]> = (0..3000)
            .map(|i| uniforms(3, 2, i).map(|u| 2.0 * u - 1.0))
            .collect();
        let batch = index.closest_batch(&queries);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap_or_else(|e| panic!("{e}"));
        let single = pool.install(|| index.closest_batch(&queries));
        assert_eq!(batch, single);
        for (q, c) in queries.iter().zip(&batch).step_by(97) {
            let one = index.closest(*q).map(|o| o.distance);
            assert_eq!(one, Some(c.distance));
        }
    }

    #[test]
    fn degenerate_triangles_and_empty_meshes() {
        let mesh = TriMesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            vec![[0, 1, 2], [0, 0, 3]],
        );
        let index = TriangleIndex::new(&mesh);
        let c = index
            .closest([1.5, 1.0, 0.0])
            .unwrap_or_else(|| panic!("none"));
        assert!((c.distance - 1.0).abs() < 1e-12);
        assert_eq!(c.triangle, 0);
        let empty = TriangleIndex::new(&TriMesh::default());
        assert!(empty.closest([0.0; 3]).is_none());
        assert!(empty.closest_batch(&[[0.0; 3]]).is_empty());
    }
}
