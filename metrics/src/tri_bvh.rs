//! A bounding volume hierarchy over triangles for exact closest-point queries.
//!
//! Median splits on the widest axis of the centroids, small leaves, flat nodes linked by
//! `u32` index. Queries visit the nearer child first and prune by box distance; ties go to the
//! first triangle found in that fixed order, so results do not depend on the thread count.

use super::geom::{closest_on_triangle, dist2, Feature, Vec3};
use super::sample::Faces;

/// Triangles per leaf.
const LEAF_SIZE: usize = 4;

/// Marks a node as a leaf in [`Node::left`].
const LEAF: u32 = u32::MAX;

/// One node: a box around all triangles below it.
#[derive(Debug, Clone, Copy)]
struct Node {
    /// Box minimum.
    lo: Vec3,
    /// Box maximum.
    hi: Vec3,
    /// First entry of `order` under this node.
    start: u32,
    /// One past the last entry of `order` under this node.
    end: u32,
    /// Index of the left child, or [`LEAF`].
    left: u32,
    /// Index of the right child (inner nodes).
    right: u32,
}

/// The closest point of a mesh to a query point.
#[derive(Debug, Clone, Copy)]
pub struct Closest {
    /// Index of the triangle it lies on.
    pub triangle: u32,
    /// The closest point.
    pub point: Vec3,
    /// Squared distance from the query.
    pub dist2: f64,
    /// Which feature of the triangle it lies on.
    pub feature: Feature,
}

/// A BVH over the triangles of a borrowed [`Faces`].
#[derive(Debug, Clone)]
pub struct TriBvh<'a> {
    /// The triangles.
    faces: &'a Faces,
    /// Triangle indices, permuted so that every node covers a contiguous range.
    order: Vec<u32>,
    /// Nodes; the root is node 0.
    nodes: Vec<Node>,
}

impl<'a> TriBvh<'a> {
    /// Builds the hierarchy over all triangles of `faces`.
    pub fn new(faces: &'a Faces) -> Self {
        let mut bvh = Self {
            faces,
            order: (0..faces.len() as u32).collect(),
            nodes: Vec::new(),
        };
        if !faces.is_empty() {
            bvh.build(0, faces.len());
        }
        bvh
    }

    /// Builds the subtree over `order[start..end]` and returns its node index.
    fn build(&mut self, start: usize, end: usize) -> u32 {
        let (lo, hi) = self.bounds(start, end);
        let id = self.nodes.len() as u32;
        self.nodes.push(Node {
            lo,
            hi,
            start: start as u32,
            end: end as u32,
            left: LEAF,
            right: LEAF,
        });
        if end - start <= LEAF_SIZE {
            return id;
        }
        let axis = (0..3)
            .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
            .unwrap_or(0);
        let mid = start + (end - start) / 2;
        let corners = &self.faces.corners;
        let centroid = |t: u32| {
            let [a, b, c] = corners[t as usize];
            a[axis] + b[axis] + c[axis]
        };
        self.order[start..end]
            .select_nth_unstable_by(mid - start, |&i, &j| centroid(i).total_cmp(&centroid(j)));
        let left = self.build(start, mid);
        let right = self.build(mid, end);
        let node = &mut self.nodes[id as usize];
        node.left = left;
        node.right = right;
        id
    }

    /// Bounding box of the triangles `order[start..end]`.
    fn bounds(&self, start: usize, end: usize) -> (Vec3, Vec3) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for &t in &self.order[start..end] {
            for p in &self.faces.corners[t as usize] {
                for a in 0..3 {
                    lo[a] = lo[a].min(p[a]);
                    hi[a] = hi[a].max(p[a]);
                }
            }
        }
        (lo, hi)
    }

    /// The closest point of the mesh to `q`, or `None` when there is no triangle.
    pub fn closest(&self, q: Vec3) -> Option<Closest> {
        if self.nodes.is_empty() {
            return None;
        }
        let mut best = Closest {
            triangle: u32::MAX,
            point: q,
            dist2: f64::INFINITY,
            feature: Feature::Face,
        };
        let mut stack: Vec<(u32, f64)> = Vec::with_capacity(64);
        stack.push((0, self.box_dist2(0, q)));
        while let Some((id, d)) = stack.pop() {
            if d >= best.dist2 {
                continue;
            }
            let node = self.nodes[id as usize];
            if node.left == LEAF {
                self.scan_leaf(&node, q, &mut best);
                continue;
            }
            let (dl, dr) = (self.box_dist2(node.left, q), self.box_dist2(node.right, q));
            // Push the farther child first so the nearer one is visited first.
            if dl <= dr {
                stack.push((node.right, dr));
                stack.push((node.left, dl));
            } else {
                stack.push((node.left, dl));
                stack.push((node.right, dr));
            }
        }
        Some(best)
    }

    /// Updates `best` with the triangles of a leaf.
    fn scan_leaf(&self, node: &Node, q: Vec3, best: &mut Closest) {
        for &t in &self.order[node.start as usize..node.end as usize] {
            let (point, feature) = closest_on_triangle(q, &self.faces.corners[t as usize]);
            let d = dist2(q, point);
            if d < best.dist2 {
                *best = Closest {
                    triangle: t,
                    point,
                    dist2: d,
                    feature,
                };
            }
        }
    }

    /// Squared distance from `q` to the box of node `id` (0 inside).
    fn box_dist2(&self, id: u32, q: Vec3) -> f64 {
        let node = &self.nodes[id as usize];
        (0..3)
            .map(|a| {
                let d = (node.lo[a] - q[a]).max(0.0).max(q[a] - node.hi[a]);
                d * d
            })
            .sum()
    }
}
