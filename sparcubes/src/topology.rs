//! Topological checks on triangle meshes: half-edge closedness, 2-manifoldness, components.
//!
//! Everything works on vertex indices only: two vertices at the same position are different
//! vertices unless the mesh is [`weld`]ed first.

use crate::mesh::TriMesh;
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};

/// What [`check`] found. A mesh is watertight when it has no boundary and no non-manifold
/// edge, and manifold when, in addition, every vertex has a single fan of triangles.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TopologyReport {
    /// Undirected edges used by exactly one triangle.
    pub boundary_edges: u64,
    /// Undirected edges used by more than two triangles.
    pub non_manifold_edges: u64,
    /// Vertices whose incident triangles form more than one fan (connected through edges at
    /// the vertex).
    pub non_manifold_vertices: u64,
    /// Edges used by two triangles in the same direction (the triangles disagree on
    /// orientation).
    pub inconsistently_oriented_edges: u64,
    /// Connected components of triangles (through shared vertices).
    pub components: u64,
    /// Triangles with a repeated vertex index (skipped by the other counts).
    pub degenerate_faces: u64,
    /// Triangles with distinct indices but zero area.
    pub zero_area_faces: u64,
}

impl TopologyReport {
    /// No boundary edge and no non-manifold edge.
    pub fn is_watertight(&self) -> bool {
        self.boundary_edges == 0 && self.non_manifold_edges == 0
    }

    /// Every edge has at most two triangles, every vertex a single fan, and no face is
    /// degenerate.
    pub fn is_manifold(&self) -> bool {
        self.non_manifold_edges == 0
            && self.non_manifold_vertices == 0
            && self.degenerate_faces == 0
    }

    /// Watertight, manifold and consistently oriented.
    pub fn is_closed_oriented_manifold(&self) -> bool {
        self.is_watertight() && self.is_manifold() && self.inconsistently_oriented_edges == 0
    }
}

fn is_degenerate(t: &[u32; 3]) -> bool {
    t[0] == t[1] || t[1] == t[2] || t[0] == t[2]
}

/// Triangles (or vertices) per parallel work item.
const CHUNK: usize = 1 << 14;

/// Checks the half-edge structure of `mesh`. Triangles with an out-of-range index count as
/// degenerate.
///
/// Every count is local: each vertex looks at the triangles around it (its link), counts the
/// edges to its higher-numbered neighbours by direction and checks that its fan is one piece,
/// so the vertices are checked in parallel with no global edge list to sort. Two passes over
/// the triangles (degrees and face checks; links), one for [`component_count`], one over
/// the vertices. All results are counts, the same whatever the thread count or the order the
/// links are filled in.
pub fn check(mesh: &TriMesh) -> TopologyReport {
    let nv = mesh.positions.len();
    let in_range = |t: &[u32; 3]| t.iter().all(|&v| (v as usize) < nv);
    let good = |t: &[u32; 3]| in_range(t) && !is_degenerate(t);

    // Pass 1: link sizes, degenerate (or out-of-range) and zero-area faces.
    let degree: Vec<AtomicU32> = (0..nv)
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(|_| AtomicU32::new(0))
        .collect();
    let [degenerate_faces, zero_area_faces] = mesh
        .triangles
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(c, tris)| {
            let mut n = [0u64; 2];
            for (k, t) in tris.iter().enumerate() {
                if !good(t) {
                    n[0] += 1;
                    continue;
                }
                for &v in t {
                    degree[v as usize].fetch_add(1, Ordering::Relaxed);
                }
                n[1] += u64::from(zero_area(mesh.triangle(c * CHUNK + k)));
            }
            n
        })
        .reduce(|| [0; 2], |a, b| [a[0] + b[0], a[1] + b[1]]);

    // Pass 2: the links.
    let links = VertexLinks::fill(&mesh.triangles, degree, good);

    let counts = (0..nv)
        .into_par_iter()
        .with_min_len(CHUNK)
        .fold(
            || (LinkCounts::default(), Scratch::default()),
            |(mut counts, mut scratch), v| {
                counts.add_vertex(v as u32, links.of(v), &mut scratch);
                (counts, scratch)
            },
        )
        .map(|(counts, _)| counts)
        .reduce(LinkCounts::default, LinkCounts::sum);

    TopologyReport {
        boundary_edges: counts.boundary_edges,
        non_manifold_edges: counts.non_manifold_edges,
        non_manifold_vertices: counts.non_manifold_vertices,
        inconsistently_oriented_edges: counts.inconsistently_oriented_edges,
        components: component_count(mesh),
        degenerate_faces,
        zero_area_faces,
    }
}

/// For every vertex, the triangles around it as the two other corners in winding order: a
/// triangle `(v, a, b)` puts `[a, b]` in the link of `v` (and `[b, v]` in that of `a`, …).
/// Compressed rows: the link of `v` is `link[start[v]..start[v + 1]]`, its entries in no
/// particular order.
struct VertexLinks {
    start: Vec<u32>,
    link: Vec<[u32; 2]>,
}

impl VertexLinks {
    /// The links of the triangles of `triangles` that pass `keep`, given each vertex's number
    /// of kept triangles (`degree`).
    fn fill(
        triangles: &[[u32; 3]],
        degree: Vec<AtomicU32>,
        keep: impl Fn(&[u32; 3]) -> bool + Sync,
    ) -> Self {
        // Exclusive prefix sum; `degree` becomes each row's fill cursor.
        let mut start = Vec::with_capacity(degree.len() + 1);
        let mut sum = 0u32;
        for d in &degree {
            start.push(sum);
            sum += d.swap(sum, Ordering::Relaxed);
        }
        start.push(sum);
        let link: Vec<[AtomicU32; 2]> = (0..sum)
            .into_par_iter()
            .with_min_len(CHUNK)
            .map(|_| [AtomicU32::new(0), AtomicU32::new(0)])
            .collect();
        triangles.par_chunks(CHUNK).for_each(|tris| {
            for t in tris {
                if !keep(t) {
                    continue;
                }
                for i in 0..3 {
                    let slot = degree[t[i] as usize].fetch_add(1, Ordering::Relaxed) as usize;
                    link[slot][0].store(t[(i + 1) % 3], Ordering::Relaxed);
                    link[slot][1].store(t[(i + 2) % 3], Ordering::Relaxed);
                }
            }
        });
        let link = link
            .into_iter()
            .map(|[a, b]| [a.into_inner(), b.into_inner()])
            .collect();
        Self { start, link }
    }

    /// The link of vertex `v`.
    fn of(&self, v: usize) -> &[[u32; 2]] {
        &self.link[self.start[v] as usize..self.start[v + 1] as usize]
    }
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
struct Scratch {
    /// The distinct neighbours of the vertex, sorted.
    neighbours: Vec<u32>,
    /// Per neighbour: triangles with the edge leaving the vertex towards it, and arriving.
    out_in: Vec<[u32; 2]>,
    /// Union-find over the neighbours, for the fan.
    parent: Vec<usize>,
}

/// Edge and vertex defects counted over some vertices; each edge is counted at its lower
/// vertex.
#[derive(Debug, Default, Clone, Copy)]
struct LinkCounts {
    boundary_edges: u64,
    non_manifold_edges: u64,
    inconsistently_oriented_edges: u64,
    non_manifold_vertices: u64,
}

impl LinkCounts {
    fn sum(self, o: Self) -> Self {
        Self {
            boundary_edges: self.boundary_edges + o.boundary_edges,
            non_manifold_edges: self.non_manifold_edges + o.non_manifold_edges,
            inconsistently_oriented_edges: self.inconsistently_oriented_edges
                + o.inconsistently_oriented_edges,
            non_manifold_vertices: self.non_manifold_vertices + o.non_manifold_vertices,
        }
    }

    /// Counts the edges from `v` to its higher neighbours and whether its fan is one piece.
    fn add_vertex(&mut self, v: u32, link: &[[u32; 2]], s: &mut Scratch) {
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

fn zero_area([a, b, c]: [[f64; 3]; 3]) -> bool {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    u[1] * v[2] == u[2] * v[1] && u[2] * v[0] == u[0] * v[2] && u[0] * v[1] == u[1] * v[0]
}

fn find(parent: &mut [usize], mut x: usize) -> usize {
    while parent[x] != x {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    x
}

/// Number of connected components of triangles (through shared vertices), as
/// [`components`] numbers them: a triangle with an out-of-range index is a component of its
/// own. Union-find in parallel (lock-free: a root is only ever linked under a smaller index,
/// by compare-and-swap), so the count does not depend on the thread count.
pub fn component_count(mesh: &TriMesh) -> u64 {
    let nv = mesh.positions.len();
    let parent: Vec<AtomicU32> = (0..nv as u32)
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(AtomicU32::new)
        .collect();
    let used: Vec<AtomicBool> = (0..nv)
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(|_| AtomicBool::new(false))
        .collect();
    let bad: u64 = mesh
        .triangles
        .par_chunks(CHUNK)
        .map(|tris| {
            let mut bad = 0;
            for t in tris {
                if t.iter().any(|&v| v as usize >= nv) {
                    bad += 1;
                    continue;
                }
                used[t[0] as usize].store(true, Ordering::Relaxed);
                for &v in &t[1..] {
                    used[v as usize].store(true, Ordering::Relaxed);
                    unite(&parent, t[0], v);
                }
            }
            bad
        })
        .sum();
    let roots: u64 = (0..nv)
        .into_par_iter()
        .with_min_len(CHUNK)
        .filter(|&v| {
            used[v].load(Ordering::Relaxed) && parent[v].load(Ordering::Relaxed) == v as u32
        })
        .count() as u64;
    roots + bad
}

/// The root of `x`, halving the path on the way.
fn find_shared(parent: &[AtomicU32], mut x: u32) -> u32 {
    loop {
        let p = parent[x as usize].load(Ordering::Acquire);
        if p == x {
            return x;
        }
        let g = parent[p as usize].load(Ordering::Acquire);
        if g != p {
            // Only ever points `x` higher up its own tree; losing the race is harmless.
            let _ = parent[x as usize].compare_exchange(p, g, Ordering::AcqRel, Ordering::Relaxed);
        }
        x = g;
    }
}

/// Joins the sets of `a` and `b`: the larger root goes under the smaller one, so no cycle can
/// form whatever the interleaving.
fn unite(parent: &[AtomicU32], a: u32, b: u32) {
    let (mut a, mut b) = (a, b);
    loop {
        let (ra, rb) = (find_shared(parent, a), find_shared(parent, b));
        if ra == rb {
            return;
        }
        let (hi, lo) = if ra > rb { (ra, rb) } else { (rb, ra) };
        if parent[hi as usize]
            .compare_exchange(hi, lo, Ordering::AcqRel, Ordering::Acquire)
            .is_ok()
        {
            return;
        }
        (a, b) = (ra, rb);
    }
}

/// Component id (`0..count`, in order of first triangle) of every triangle, where triangles
/// sharing a vertex are connected. Triangles with an out-of-range index get their own
/// component.
pub fn components(mesh: &TriMesh) -> Vec<u32> {
    let nv = mesh.positions.len();
    let mut parent: Vec<usize> = (0..nv).collect();
    for t in &mesh.triangles {
        if t.iter().any(|&v| v as usize >= nv) {
            continue;
        }
        let a = find(&mut parent, t[0] as usize);
        for &v in &t[1..] {
            let b = find(&mut parent, v as usize);
            if a != b {
                parent[b] = a;
            }
        }
    }
    let mut id_of_root: HashMap<usize, u32> = HashMap::new();
    let mut next = 0u32;
    let mut out = Vec::with_capacity(mesh.triangles.len());
    for t in &mesh.triangles {
        let root = if t.iter().any(|&v| v as usize >= nv) {
            usize::MAX - out.len()
        } else {
            find(&mut parent, t[0] as usize)
        };
        let id = *id_of_root.entry(root).or_insert_with(|| {
            next += 1;
            next - 1
        });
        out.push(id);
    }
    out
}

/// Merges vertices with bit-identical positions (`-0.0` equals `0.0`), keeping the first
/// occurrence's order; unused vertices are kept.
pub fn weld(mesh: &TriMesh) -> TriMesh {
    let mut map: HashMap<[u32; 3], u32> = HashMap::with_capacity(mesh.positions.len());
    let mut positions = Vec::new();
    let remap: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            let key = p.map(|x| (x + 0.0).to_bits());
            *map.entry(key).or_insert_with(|| {
                positions.push(*p);
                positions.len() as u32 - 1
            })
        })
        .collect();
    let triangles = mesh
        .triangles
        .iter()
        .map(|t| t.map(|v| remap.get(v as usize).copied().unwrap_or(v)))
        .collect();
    TriMesh::new(positions, triangles)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> TriMesh {
        TriMesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ],
            vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
        )
    }

    #[test]
    fn tetrahedron_is_closed() {
        let r = check(&tetra());
        assert!(r.is_closed_oriented_manifold(), "{r:?}");
        assert_eq!(r.components, 1);
        assert!(tetra().signed_volume() > 0.0);
    }

    #[test]
    fn defects_are_counted() {
        let mut m = tetra();
        m.triangles.pop();
        let r = check(&m);
        assert_eq!(r.boundary_edges, 3);
        assert!(!r.is_watertight());

        let mut m = tetra();
        m.triangles[0] = [0, 1, 2];
        assert_eq!(check(&m).inconsistently_oriented_edges, 3);

        let mut m = tetra();
        m.positions.push([1.0, 1.0, 1.0]);
        m.triangles.push([0, 1, 4]);
        let r = check(&m);
        assert_eq!(r.non_manifold_edges, 1);

        // Two tetrahedra sharing only vertex 0.
        let mut m = tetra();
        let off = m.positions.len() as u32;
        m.positions
            .extend([[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]);
        for t in tetra().triangles {
            m.triangles
                .push(t.map(|v| if v == 0 { 0 } else { v - 1 + off }));
        }
        let r = check(&m);
        assert!(r.is_watertight());
        assert_eq!(r.non_manifold_vertices, 1);
        assert!(!r.is_manifold());
        assert_eq!(r.components, 1);

        let mut m = tetra();
        m.triangles.push([1, 1, 2]);
        assert_eq!(check(&m).degenerate_faces, 1);

        // A degenerate face on vertices of its own is still a component.
        m.positions.extend([[5.0, 0.0, 0.0], [6.0, 0.0, 0.0]]);
        m.triangles.push([4, 5, 5]);
        let r = check(&m);
        assert_eq!((r.degenerate_faces, r.components), (2, 2));
        assert_eq!(component_count(&m), 2);
    }

    #[test]
    fn large_meshes_are_counted_across_chunks() {
        // Two tori (closed, 2 × 2 × 200² triangles, more than one parallel chunk) and an open
        // cylinder whose rims are boundary edges.
        let torus = crate::shapes::torus([0.0; 3], 2.0, 0.5, 200);
        let far = crate::shapes::torus([10.0, 0.0, 0.0], 2.0, 0.5, 200);
        let tube = crate::shapes::open_cylinder([0.0, 20.0], 1.0, 0.0, 1.0, 64);
        let both = crate::shapes::merge(&[torus.clone(), far]);
        let r = check(&both);
        assert!(r.is_closed_oriented_manifold(), "{r:?}");
        assert_eq!((r.components, component_count(&both)), (2, 2));
        let r = check(&tube);
        assert_eq!(r.boundary_edges, 2 * 64, "{r:?}");
        assert_eq!((r.non_manifold_edges, r.components), (0, 1));

        // Flipping one triangle of the torus breaks the orientation of its three edges.
        let mut m = torus;
        m.triangles[17_000].swap(1, 2);
        let r = check(&m);
        assert_eq!(r.inconsistently_oriented_edges, 3);
        assert!(r.is_watertight() && r.is_manifold());
    }

    #[test]
    fn weld_merges_identical_positions() {
        let m = TriMesh::new(
            vec![
                [0.0; 3],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [-0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            vec![[0, 1, 2], [3, 4, 1]],
        );
        let w = weld(&m);
        assert_eq!(w.positions.len(), 3);
        assert_eq!(w.triangles, vec![[0, 1, 2], [0, 2, 1]]);
        assert_eq!(components(&w), vec![0, 0]);
    }
}
