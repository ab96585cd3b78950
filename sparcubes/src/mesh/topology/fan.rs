//! The per-vertex half of [`super::check`]: from the link of one vertex (the triangles
//! around it), the defects of the edges it is the lower end of and whether its triangles form
//! a single fan.

/// The three link entries of a good triangle `t`, each with its vertex: `(v, a, b)` puts
/// `[a, b]` in the link of `v`, `[b, v]` in that of `a` and `[v, a]` in that of `b`, so every
/// entry lists the other two corners in winding order.
#[inline]
pub(super) fn link_entries(t: &[u32; 3]) -> [(u32, [u32; 2]); 3] {
    [
        (t[0], [t[1], t[2]]),
        (t[1], [t[2], t[0]]),
        (t[2], [t[0], t[1]]),
    ]
}

/// Whether `link` is one closed fan, consistently oriented: following each triangle to the
/// one that continues it (whose first corner is this one's second) visits every triangle once
/// and comes back. Then every edge at the vertex has one triangle on each side, in opposite
/// directions, and there is nothing to count. Only for small links (the common case); larger
/// or broken ones take the general path.
fn is_closed_fan(link: &[[u32; 2]]) -> bool {
    let k = link.len();
    if !(3..=64).contains(&k) {
        return false;
    }
    let (mut at, mut seen) = (0usize, 0u64);
    for _ in 0..k {
        if seen >> at & 1 == 1 {
            return false;
        }
        seen |= 1 << at;
        let b = link[at][1];
        match link.iter().position(|e| e[0] == b) {
            Some(next) => at = next,
            None => return false,
        }
    }
    // k steps over k distinct triangles, back at the first: one cycle through all of them,
    // so the map to the continuing triangle is one-to-one and no corner repeats.
    at == 0 && seen.count_ones() as usize == k
}

/// Reused buffers of [`LinkCounts::add_vertex`].
#[derive(Default)]
pub(super) struct Scratch {
    /// The distinct neighbours of the vertex, sorted.
    neighbours: Vec<u32>,
    /// Per neighbour: triangles with the edge leaving the vertex towards it, and arriving.
    out_in: Vec<[u32; 2]>,
    /// Union-find over the neighbours, for the fan.
    parent: Vec<usize>,
}

/// Edge and vertex defects counted over some vertices; each edge is counted at its lower
/// vertex.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub(super) struct LinkCounts {
    pub(super) boundary_edges: u64,
    pub(super) non_manifold_edges: u64,
    pub(super) inconsistently_oriented_edges: u64,
    pub(super) non_manifold_vertices: u64,
}

impl LinkCounts {
    /// The counts of both sets of vertices.
    pub(super) fn sum(self, o: Self) -> Self {
        Self {
            boundary_edges: self.boundary_edges + o.boundary_edges,
            non_manifold_edges: self.non_manifold_edges + o.non_manifold_edges,
            inconsistently_oriented_edges: self.inconsistently_oriented_edges
                + o.inconsistently_oriented_edges,
            non_manifold_vertices: self.non_manifold_vertices + o.non_manifold_vertices,
        }
    }

    /// Counts the edges from `v` to its higher neighbours and whether its fan is one piece.
    pub(super) fn add_vertex(&mut self, v: u32, link: &[[u32; 2]], s: &mut Scratch) {
        if link.is_empty() || is_closed_fan(link) {
            return;
        }
        s.neighbours.clear();
        s.neighbours.extend(link.iter().flatten());
        s.neighbours.sort_unstable();
        s.neighbours.dedup();
        s.out_in.clear();
        s.out_in.resize(s.neighbours.len(), [0, 0]);
        s.parent.clear();
        s.parent.extend(0..s.neighbours.len());
        let mut groups = s.neighbours.len();
        for &[a, b] in link {
            // Triangle (v, a, b): the edge v→a leaves v, the edge b→v arrives.
            let ia = s.neighbours.binary_search(&a).unwrap_or(0);
            let ib = s.neighbours.binary_search(&b).unwrap_or(0);
            s.out_in[ia][0] += 1;
            s.out_in[ib][1] += 1;
            let (ra, rb) = (find(&mut s.parent, ia), find(&mut s.parent, ib));
            if ra != rb {
                s.parent[ra] = rb;
                groups -= 1;
            }
        }
        if link.len() >= 2 && groups > 1 {
            self.non_manifold_vertices += 1;
        }
        let first_higher = s.neighbours.partition_point(|&w| w < v);
        for &[out, arrive] in &s.out_in[first_higher..] {
            match out + arrive {
                1 => self.boundary_edges += 1,
                2 => {
                    if out != 1 {
                        self.inconsistently_oriented_edges += 1;
                    }
                }
                _ => self.non_manifold_edges += 1,
            }
        }
    }
}

/// The root of `x` in a union-find forest, halving the path on the way.
pub(super) fn find(parent: &mut [usize], mut x: usize) -> usize {
    while parent[x] != x {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    x
}
