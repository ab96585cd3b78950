//! Farthest point sampling, exact and deterministic: the first point is point 0, each next one
//! the point farthest from those chosen (ties to the lowest index), as a consumer that keeps
//! a farthest-point subset of its surface and sharp points takes it (`fpsample`'s
//! `bucket_fps_kdline_sampling`; which consumer and where: docs/FORMAT.md, "Samples for
//! vector-set VAEs").
//!
//! The points are bucketed into a kd-tree with leaves of at most [`LEAF`] points. Every node
//! keeps its bounding box and its best point: the largest distance to the chosen set of the
//! points under it (with the lowest index among equals). A new chosen point `q` lowers the
//! distances of a node's points only if it is nearer to the node's box than that largest
//! distance, so every other node is skipped; the root's best point is the next one chosen.
//! Early on most leaves are visited; as the distances shrink, only the leaves around `q`.
//!
//! Distances are squared, in `f32`, all computed by [`dist2`]. The skip is exact: for a point
//! `p` in a box, every rounded difference `p − q` is at least the rounded gap between `q` and
//! the box on that axis (rounding is monotonic), so `dist2(p, q)` is at least the box's, and a
//! skipped node holds no point whose distance would have dropped.

/// Most points in one leaf of the tree.
const LEAF: usize = 64;

/// Squared distance of two points, in `f32`, summed x, y, z in that order.
#[inline]
pub(crate) fn dist2(a: [f32; 3], b: [f32; 3]) -> f32 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// Squared distance from `q` to the box `[lo, hi]` (0 inside), as [`dist2`] sums it.
#[inline]
fn box_dist2(q: [f32; 3], lo: [f32; 3], hi: [f32; 3]) -> f32 {
    let gap = |a: usize| {
        if q[a] < lo[a] {
            lo[a] - q[a]
        } else if q[a] > hi[a] {
            q[a] - hi[a]
        } else {
            0.0
        }
    };
    let d = [gap(0), gap(1), gap(2)];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// The better of two candidates `(distance, index)`: the farther, then the lower index.
#[inline]
fn better(a: (f32, u32), b: (f32, u32)) -> bool {
    a.0 > b.0 || (a.0 == b.0 && a.1 < b.1)
}

/// A node of the tree over positions `start..end` of the reordered points.
#[derive(Debug, Clone)]
struct Node {
    /// Smallest corner of the points' bounding box.
    lo: [f32; 3],
    /// Largest corner.
    hi: [f32; 3],
    /// First position under the node.
    start: u32,
    /// One past the last position.
    end: u32,
    /// The two children (node numbers), `None` for a leaf.
    children: Option<(u32, u32)>,
    /// Largest distance to the chosen set under the node, with the point's index; −1 when
    /// every point under it is chosen.
    best: (f32, u32),
    /// Position of the best point.
    best_pos: u32,
}

/// The tree and the distances of every point to the chosen set.
struct Tree {
    /// The nodes; node 0 is the root.
    nodes: Vec<Node>,
    /// Points in leaf order.
    points: Vec<[f32; 3]>,
    /// Index in the input of each reordered point.
    ids: Vec<u32>,
    /// Squared distance of each reordered point to the chosen set (∞ before the first, −1
    /// once chosen).
    dist: Vec<f32>,
}

/// Indices of `count` points of `points` by farthest point sampling (module docs), in the
/// order chosen; all of them (in that order) when there are no more than `count`. Duplicate
/// points are chosen last, by index, once every distinct point is. Only the first
/// `u32::MAX` points are considered.
pub fn farthest_points(points: &[[f32; 3]], count: usize) -> Vec<u32> {
    let n = points.len().min(u32::MAX as usize);
    let count = count.min(n);
    if count == 0 {
        return Vec::new();
    }
    let mut tree = Tree::new(&points[..n]);
    let mut out = Vec::with_capacity(count);
    // Point 0 first, at its position in leaf order.
    let mut pos = tree.ids.iter().position(|&i| i == 0).unwrap_or(0);
    while out.len() < count {
        out.push(tree.ids[pos]);
        tree.choose(0, pos);
        pos = tree.nodes[0].best_pos as usize;
    }
    out
}

impl Tree {
    /// The tree of `points` (at most `u32::MAX`), no point chosen yet.
    fn new(points: &[[f32; 3]]) -> Self {
        let mut ids: Vec<u32> = (0..points.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * points.len().div_ceil(LEAF) + 1);
        build(points, &mut ids, 0, &mut nodes);
        Self {
            nodes,
            points: ids.iter().map(|&i| points[i as usize]).collect(),
            dist: vec![f32::INFINITY; ids.len()],
            ids,
        }
    }

    /// Chooses the point at position `pos`: lowers the distances under `node` to it, marks it
    /// chosen, and updates the best points on the way back.
    fn choose(&mut self, node: usize, pos: usize) {
        let q = self.points[pos];
        let nd = &self.nodes[node];
        let holds = (nd.start as usize..nd.end as usize).contains(&pos);
        if !holds && box_dist2(q, nd.lo, nd.hi) >= nd.best.0 {
            return;
        }
        let children = nd.children;
        match children {
            None => self.choose_in_leaf(node, pos, q),
            Some((left, right)) => {
                self.choose(left as usize, pos);
                self.choose(right as usize, pos);
                let (l, r) = (&self.nodes[left as usize], &self.nodes[right as usize]);
                let (best, best_pos) = if better(r.best, l.best) {
                    (r.best, r.best_pos)
                } else {
                    (l.best, l.best_pos)
                };
                self.nodes[node].best = best;
                self.nodes[node].best_pos = best_pos;
            }
        }
    }

    /// [`Tree::choose`] in a leaf: every distance lowered to `q`, the chosen one marked.
    fn choose_in_leaf(&mut self, node: usize, pos: usize, q: [f32; 3]) {
        let (start, end) = (
            self.nodes[node].start as usize,
            self.nodes[node].end as usize,
        );
        let mut best = (-1.0f32, u32::MAX);
        let mut best_pos = start;
        for i in start..end {
            let d = if i == pos {
                -1.0
            } else {
                self.dist[i].min(dist2(self.points[i], q))
            };
            self.dist[i] = d;
            if better((d, self.ids[i]), best) {
                best = (d, self.ids[i]);
                best_pos = i;
            }
        }
        self.nodes[node].best = best;
        self.nodes[node].best_pos = best_pos as u32;
    }
}

/// Builds the subtree over `ids` (positions from `start`) into `nodes`, reordering `ids` so
/// that every node's points are contiguous; returns the subtree's node number. A node of more
/// than [`LEAF`] points is split at the median of its box's longest axis (ties by index, so
/// the tree depends on the points alone).
fn build(points: &[[f32; 3]], ids: &mut [u32], start: usize, nodes: &mut Vec<Node>) -> u32 {
    let (lo, hi) = bounds(points, ids);
    let number = nodes.len() as u32;
    // The lowest index under the node is the best before anything is chosen.
    let first = ids.iter().enumerate().min_by_key(|&(_, &i)| i);
    let (best_pos, best_id) = first.map_or((start, 0), |(p, &i)| (start + p, i));
    nodes.push(Node {
        lo,
        hi,
        start: start as u32,
        end: (start + ids.len()) as u32,
        children: None,
        best: (f32::INFINITY, best_id),
        best_pos: best_pos as u32,
    });
    if ids.len() > LEAF {
        let axis = (0..3)
            .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
            .unwrap_or(0);
        let mid = ids.len() / 2;
        let key = |i: &u32| (points[*i as usize][axis], *i);
        ids.select_nth_unstable_by(mid, |a, b| {
            let (ka, kb) = (key(a), key(b));
            ka.0.total_cmp(&kb.0).then(ka.1.cmp(&kb.1))
        });
        let (left_ids, right_ids) = ids.split_at_mut(mid);
        let left = build(points, left_ids, start, nodes);
        let right = build(points, right_ids, start + mid, nodes);
        nodes[number as usize].children = Some((left, right));
    }
    number
}

/// The bounding box of the points `ids`.
fn bounds(points: &[[f32; 3]], ids: &[u32]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for &i in ids {
        let p = points[i as usize];
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::products::samples::rng::Draw;

    /// Farthest point sampling by its definition, over every point at every step.
    fn brute_force(points: &[[f32; 3]], count: usize) -> Vec<u32> {
        let mut dist = vec![f32::INFINITY; points.len()];
        let mut out = Vec::new();
        let mut next = 0usize;
        while out.len() < count.min(points.len()) {
            out.push(next as u32);
            dist[next] = -1.0;
            let q = points[next];
            let mut best = (-1.0f32, u32::MAX);
            for (i, p) in points.iter().enumerate() {
                if dist[i] >= 0.0 {
                    dist[i] = dist[i].min(dist2(*p, q));
                }
                if better((dist[i], i as u32), best) {
                    best = (dist[i], i as u32);
                    next = i;
                }
            }
        }
        out
    }

    fn random_points(n: u64, seed: u64) -> Vec<[f32; 3]> {
        (0..n)
            .map(|i| {
                let d = Draw::new(seed, 9, i);
                [0, 1, 2].map(|a| (2.0 * d.uniform(a) - 1.0) as f32)
            })
            .collect()
    }

    #[test]
    fn the_same_as_brute_force() {
        // Uniform in a cube, and on a sphere (a surface, like the samples it is meant for).
        let cube = random_points(3000, 1);
        let sphere: Vec<[f32; 3]> = random_points(3000, 2)
            .into_iter()
            .map(|p| {
                let l = dist2(p, [0.0; 3]).sqrt().max(1e-6);
                p.map(|c| c / l)
            })
            .collect();
        for (name, points) in [("cube", cube), ("sphere", sphere)] {
            for count in [1, 2, 100, 1000, 3000] {
                assert_eq!(
                    farthest_points(&points, count),
                    brute_force(&points, count),
                    "{name}, {count} points"
                );
            }
        }
    }

    #[test]
    fn duplicates_and_too_few_points() {
        // 40 points on a coarse lattice, each repeated 5 times: the 40 distinct ones first.
        let points: Vec<[f32; 3]> = (0..200u32)
            .map(|i| {
                let j = i % 40;
                [(j % 4) as f32, ((j / 4) % 5) as f32, (j / 20) as f32]
            })
            .collect();
        for count in [10, 40, 41, 150, 200, 500] {
            let got = farthest_points(&points, count);
            assert_eq!(got, brute_force(&points, count), "{count}");
            assert_eq!(got.len(), count.min(200));
            let mut seen = got.clone();
            seen.sort_unstable();
            seen.dedup();
            assert_eq!(seen.len(), got.len(), "an index chosen twice");
        }
        let first_40: Vec<u32> = farthest_points(&points, 40);
        let mut distinct: Vec<u32> = first_40.iter().map(|&i| i % 40).collect();
        distinct.sort_unstable();
        distinct.dedup();
        assert_eq!(
            distinct.len(),
            40,
            "every distinct point before any duplicate"
        );
        // All the same point, none, fewer than asked.
        assert_eq!(farthest_points(&[[1.0; 3]; 5], 3), vec![0, 1, 2]);
        assert_eq!(farthest_points(&[], 3), Vec::<u32>::new());
        assert_eq!(farthest_points(&random_points(3, 3), 0), Vec::<u32>::new());
        assert_eq!(farthest_points(&random_points(100, 3), 1000).len(), 100);
    }
}
