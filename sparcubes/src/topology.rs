//! Topological checks on triangle meshes: half-edge closedness, 2-manifoldness, components.
//!
//! Everything works on vertex indices only: two vertices at the same position are different
//! vertices unless the mesh is [`weld`]ed first.

use crate::mesh::TriMesh;
use std::collections::HashMap;

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

/// Checks the half-edge structure of `mesh`. Triangles with an out-of-range index count as
/// degenerate.
pub fn check(mesh: &TriMesh) -> TopologyReport {
    let nv = mesh.positions.len();
    let mut report = TopologyReport::default();
    let mut good: Vec<[u32; 3]> = Vec::with_capacity(mesh.triangles.len());
    for (ti, t) in mesh.triangles.iter().enumerate() {
        if is_degenerate(t) || t.iter().any(|&v| v as usize >= nv) {
            report.degenerate_faces += 1;
            continue;
        }
        if zero_area(mesh.triangle(ti)) {
            report.zero_area_faces += 1;
        }
        good.push(*t);
    }

    // Edges: (lo, hi, forward) sorted, then grouped.
    let mut edges: Vec<(u32, u32, bool)> = Vec::with_capacity(good.len() * 3);
    for t in &good {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            edges.push((a.min(b), a.max(b), a < b));
        }
    }
    edges.sort_unstable();
    let mut i = 0;
    while i < edges.len() {
        let mut j = i;
        while j < edges.len() && edges[j].0 == edges[i].0 && edges[j].1 == edges[i].1 {
            j += 1;
        }
        match j - i {
            1 => report.boundary_edges += 1,
            2 => {
                if edges[i].2 == edges[i + 1].2 {
                    report.inconsistently_oriented_edges += 1;
                }
            }
            _ => report.non_manifold_edges += 1,
        }
        i = j;
    }

    // Vertex fans: the link of each vertex (the opposite edges of its triangles) must be
    // connected.
    let mut start = vec![0u32; nv + 1];
    for t in &good {
        for &v in t {
            start[v as usize + 1] += 1;
        }
    }
    for v in 0..nv {
        start[v + 1] += start[v];
    }
    let mut fill = start.clone();
    let mut link = vec![[0u32; 2]; good.len() * 3];
    for t in &good {
        for i in 0..3 {
            let v = t[i] as usize;
            link[fill[v] as usize] = [t[(i + 1) % 3], t[(i + 2) % 3]];
            fill[v] += 1;
        }
    }
    let mut local: Vec<u32> = Vec::new();
    let mut parent: Vec<usize> = Vec::new();
    for v in 0..nv {
        let l = &link[start[v] as usize..start[v + 1] as usize];
        if l.len() < 2 {
            continue;
        }
        local.clear();
        local.extend(l.iter().flatten());
        local.sort_unstable();
        local.dedup();
        parent.clear();
        parent.extend(0..local.len());
        let mut groups = local.len();
        for e in l {
            let a = find(&mut parent, local.binary_search(&e[0]).unwrap_or(0));
            let b = find(&mut parent, local.binary_search(&e[1]).unwrap_or(0));
            if a != b {
                parent[a] = b;
                groups -= 1;
            }
        }
        if groups > 1 {
            report.non_manifold_vertices += 1;
        }
    }

    let ids = components(mesh);
    report.components = ids.iter().map(|&c| c as u64 + 1).max().unwrap_or(0);
    report
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
