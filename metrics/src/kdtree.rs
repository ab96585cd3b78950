//! A static kd-tree over points for exact nearest-neighbour queries.
//!
//! Built once (median splits on the widest axis, small leaves), queried from many threads.
//! Queries are exact, and ties go to the first point found in a fixed traversal order, so
//! results do not depend on the thread count.

use super::geom::{dist2, Vec3};

/// Points per leaf.
const LEAF_SIZE: usize = 8;

/// Marks a node as a leaf in [`Node::left`].
const LEAF: u32 = u32::MAX;

/// One node: an inner node splits at `split` on `axis`; a leaf holds `order[start..end]`.
#[derive(Debug, Clone, Copy)]
struct Node {
    /// Split coordinate (inner nodes).
    split: f64,
    /// Split axis, 0..3 (inner nodes).
    axis: u8,
    /// First entry of `order` under this node.
    start: u32,
    /// One past the last entry of `order` under this node.
    end: u32,
    /// Index of the left child, or [`LEAF`].
    left: u32,
    /// Index of the right child (inner nodes).
    right: u32,
}

/// A kd-tree over a borrowed point set.
#[derive(Debug, Clone)]
pub struct KdTree<'a> {
    /// The points, indexed as given.
    points: &'a [Vec3],
    /// Point indices, permuted so that every node covers a contiguous range.
    order: Vec<u32>,
    /// Nodes; the root is node 0.
    nodes: Vec<Node>,
}

impl<'a> KdTree<'a> {
    /// Builds the tree over `points`.
    pub fn new(points: &'a [Vec3]) -> Self {
        let mut tree = Self {
            points,
            order: (0..points.len() as u32).collect(),
            nodes: Vec::new(),
        };
        if !points.is_empty() {
            tree.build(0, points.len());
        }
        tree
    }

    /// Builds the subtree over `order[start..end]` and returns its node index.
    fn build(&mut self, start: usize, end: usize) -> u32 {
        let id = self.nodes.len() as u32;
        self.nodes.push(Node {
            split: 0.0,
            axis: 0,
            start: start as u32,
            end: end as u32,
            left: LEAF,
            right: LEAF,
        });
        if end - start <= LEAF_SIZE {
            return id;
        }
        let axis = self.widest_axis(start, end);
        let mid = start + (end - start) / 2;
        let points = self.points;
        self.order[start..end].select_nth_unstable_by(mid - start, |&i, &j| {
            points[i as usize][axis].total_cmp(&points[j as usize][axis])
        });
        let split = points[self.order[mid] as usize][axis];
        let left = self.build(start, mid);
        let right = self.build(mid, end);
        let node = &mut self.nodes[id as usize];
        node.split = split;
        node.axis = axis as u8;
        node.left = left;
        node.right = right;
        id
    }

    /// The axis along which `order[start..end]` spreads most.
    fn widest_axis(&self, start: usize, end: usize) -> usize {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for &i in &self.order[start..end] {
            let p = self.points[i as usize];
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        (0..3)
            .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
            .unwrap_or(0)
    }

    /// The nearest point to `q`: `(index, squared distance)`, or `None` for an empty tree.
    pub fn nearest(&self, q: Vec3) -> Option<(u32, f64)> {
        if self.nodes.is_empty() {
            return None;
        }
        let mut best = (u32::MAX, f64::INFINITY);
        self.descend(0, q, &mut best);
        Some(best)
    }

    /// Searches node `id`, nearer child first, pruning by the split plane.
    fn descend(&self, id: u32, q: Vec3, best: &mut (u32, f64)) {
        let node = self.nodes[id as usize];
        if node.left == LEAF {
            for &i in &self.order[node.start as usize..node.end as usize] {
                let d = dist2(q, self.points[i as usize]);
                if d < best.1 {
                    *best = (i, d);
                }
            }
            return;
        }
        let diff = q[node.axis as usize] - node.split;
        let (near, far) = if diff < 0.0 {
            (node.left, node.right)
        } else {
            (node.right, node.left)
        };
        self.descend(near, q, best);
        if diff * diff < best.1 {
            self.descend(far, q, best);
        }
    }
}
