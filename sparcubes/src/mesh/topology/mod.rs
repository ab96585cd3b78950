//! Topological checks on triangle meshes: half-edge closedness, 2-manifoldness, components.
//!
//! Everything works on vertex indices only: two vertices at the same position are different
//! vertices unless the mesh is [`weld`]ed first.

mod fan;
mod forest;
mod links;
mod tiles;

use crate::mesh::TriMesh;
use fan::find;
use forest::ComponentForest;
use rayon::prelude::*;
use std::collections::HashMap;
use tiles::TileSet;

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
const CHUNK: usize = 1 << 12;

/// Checks the half-edge structure of `mesh`. Triangles with an out-of-range index count as
/// degenerate.
///
/// Every count is local: each vertex looks at the triangles around it (its link), counts the
/// edges to its higher-numbered neighbours by direction and checks that its fan is one piece,
/// so the vertices are checked in parallel with no global edge list to sort. One pass over
/// the triangles counts the degenerate and zero-area faces, joins the components and notes
/// which vertices each chunk of triangles uses; the links are then filled and read tile by
/// tile of vertices (`tiles`) where the triangles come in an order close to their
/// vertices', as in every output of [`crate::extract()`], and all at once (`links`)
/// otherwise. All results are counts, the same whatever the thread count, the path or the
/// order the links are filled in.
pub fn check(mesh: &TriMesh) -> TopologyReport {
    let nv = mesh.positions.len();
    let forest = ComponentForest::new(nv);
    let faces = FaceScan::of(mesh, &forest);
    let counts = link_counts(&mesh.triangles, nv, &faces.chunk_tiles);
    TopologyReport {
        boundary_edges: counts.boundary_edges,
        non_manifold_edges: counts.non_manifold_edges,
        non_manifold_vertices: counts.non_manifold_vertices,
        inconsistently_oriented_edges: counts.inconsistently_oriented_edges,
        components: forest.used_sets() + faces.out_of_range,
        degenerate_faces: faces.out_of_range + faces.degenerate,
        zero_area_faces: faces.zero_area,
    }
}

/// The edge and vertex defects of the good triangles of `triangles`, tile by tile where
/// `chunk_tiles` (from [`FaceScan`]) says that is cheap, all at once otherwise.
fn link_counts(triangles: &[[u32; 3]], nv: usize, chunk_tiles: &[TileSet]) -> fan::LinkCounts {
    tiles::link_counts(triangles, chunk_tiles, nv)
        .unwrap_or_else(|| links::link_counts(triangles, nv))
}

/// What [`check`]'s pass over the triangles found: the counts of bad faces, and per chunk
/// of [`CHUNK`] triangles the tiles of the vertices of its good ones.
struct FaceScan {
    out_of_range: u64,
    degenerate: u64,
    zero_area: u64,
    chunk_tiles: Vec<TileSet>,
}

impl FaceScan {
    /// Scans the triangles of `mesh` in parallel, joining the components of those in range
    /// in `forest`.
    fn of(mesh: &TriMesh, forest: &ComponentForest) -> Self {
        let nv = mesh.positions.len();
        let chunks: Vec<([u64; 3], TileSet)> = mesh
            .triangles
            .par_chunks(CHUNK)
            .enumerate()
            .map(|(c, tris)| {
                let mut bad = [0u64; 3];
                let mut tiles = TileSet::new(nv);
                for (k, t) in tris.iter().enumerate() {
                    if !in_range(t, nv) {
                        bad[0] += 1;
                        continue;
                    }
                    forest.join(t);
                    if is_degenerate(t) {
                        bad[1] += 1;
                        continue;
                    }
                    bad[2] += u64::from(zero_area(mesh.triangle(c * CHUNK + k)));
                    for &v in t {
                        tiles.insert(v);
                    }
                }
                (bad, tiles)
            })
            .collect();
        let mut scan = Self {
            out_of_range: 0,
            degenerate: 0,
            zero_area: 0,
            chunk_tiles: Vec::with_capacity(chunks.len()),
        };
        for ([out_of_range, degenerate, zero_area], tiles) in chunks {
            scan.out_of_range += out_of_range;
            scan.degenerate += degenerate;
            scan.zero_area += zero_area;
            scan.chunk_tiles.push(tiles);
        }
        scan
    }
}

/// In range and not degenerate: the triangles that count in the links.
fn is_good(t: &[u32; 3], nv: usize) -> bool {
    in_range(t, nv) && !is_degenerate(t)
}

/// Whether every index of `t` is below `nv`.
fn in_range(t: &[u32; 3], nv: usize) -> bool {
    t.iter().all(|&v| (v as usize) < nv)
}

fn zero_area([a, b, c]: [[f64; 3]; 3]) -> bool {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    u[1] * v[2] == u[2] * v[1] && u[2] * v[0] == u[0] * v[2] && u[0] * v[1] == u[1] * v[0]
}

/// Number of connected components of triangles (through shared vertices), as
/// [`components`] numbers them: a triangle with an out-of-range index is a component of its
/// own. Union-find in parallel (`ComponentForest`), so the count does not depend on the
/// thread count.
pub fn component_count(mesh: &TriMesh) -> u64 {
    let nv = mesh.positions.len();
    let forest = ComponentForest::new(nv);
    let out_of_range: u64 = mesh
        .triangles
        .par_chunks(CHUNK)
        .map(|tris| {
            let mut bad = 0;
            for t in tris {
                if in_range(t, nv) {
                    forest.join(t);
                } else {
                    bad += 1;
                }
            }
            bad
        })
        .sum();
    forest.used_sets() + out_of_range
}

/// Component id (`0..count`, in order of first triangle) of every triangle, where triangles
/// sharing a vertex are connected. Triangles with an out-of-range index get their own
/// component.
pub fn components(mesh: &TriMesh) -> Vec<u32> {
    let nv = mesh.positions.len();
    let mut parent: Vec<usize> = (0..nv).collect();
    for t in &mesh.triangles {
        if !in_range(t, nv) {
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
        let root = if !in_range(t, nv) {
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

    /// The link counts of both paths, the tiled one `None` where it declines.
    fn both_paths(m: &TriMesh) -> (Option<fan::LinkCounts>, fan::LinkCounts) {
        let nv = m.positions.len();
        let faces = FaceScan::of(m, &ComponentForest::new(nv));
        (
            tiles::link_counts(&m.triangles, &faces.chunk_tiles, nv),
            links::link_counts(&m.triangles, nv),
        )
    }

    /// Two tori of 2 × 2 × 400² triangles, 320,000 vertices: five tiles.
    fn two_tori() -> TriMesh {
        let torus = crate::shapes::torus([0.0; 3], 2.0, 0.5, 400);
        let far = crate::shapes::torus([10.0, 0.0, 0.0], 2.0, 0.5, 400);
        crate::shapes::merge(&[torus, far])
    }

    #[test]
    fn tiles_count_what_the_general_path_counts() {
        let closed = two_tori();
        assert!(closed.positions.len() > 4 * tiles::TILE);
        let mut broken = closed.clone();
        // Defects in every tile and on the tiles' borders: a flipped triangle, a missing one,
        // a degenerate one, a triangle on an existing edge (non-manifold) and one joining
        // the tori at a vertex each (two non-manifold vertices).
        broken.triangles[17_000].swap(1, 2);
        broken.triangles.remove(200_000);
        broken.triangles[300_000][1] = broken.triangles[300_000][0];
        let [a, b, _] = broken.triangles[100_000];
        let far = broken.positions.len() as u32 - 1;
        broken.triangles.push([b, a, far]);
        let near = tiles::TILE as u32 - 1;
        broken.triangles.push([0, near, far - 5]);
        let (tiled, general) = both_paths(&broken);
        assert_eq!(tiled, Some(general));
        // Boundary edges: 3 of the missing triangle, 3 of the degenerate one, 2 + 3 of the
        // added ones; non-manifold vertices: the three corners of the last and `far`.
        let r = check(&broken);
        assert_eq!(
            (
                r.boundary_edges,
                r.non_manifold_edges,
                r.inconsistently_oriented_edges
            ),
            (11, 1, 3),
            "{r:?}"
        );
        assert_eq!(r.non_manifold_vertices, 4);
        assert_eq!((r.degenerate_faces, r.components), (1, 1));

        let (tiled, general) = both_paths(&closed);
        assert_eq!(tiled, Some(general));
        assert_eq!(general, fan::LinkCounts::default());
    }

    #[test]
    fn a_vertex_with_a_long_link_is_checked_whole() {
        // The poles of a UV sphere have 2 × 40 triangles around them, more than a tile's row
        // holds; one missing pole triangle opens two edges there.
        let mut m = crate::shapes::sphere([0.0; 3], 1.0, 40);
        let r = check(&m);
        assert!(r.is_closed_oriented_manifold(), "{r:?}");
        m.triangles.remove(0);
        let (tiled, general) = both_paths(&m);
        assert_eq!(tiled, Some(general));
        assert_eq!(
            (general.boundary_edges, general.non_manifold_vertices),
            (3, 0)
        );
    }

    #[test]
    fn triangles_in_no_vertex_order_take_the_general_path() {
        // The same tori with their vertices renumbered at random: every chunk of triangles
        // uses every tile, the tiles decline, and the report is the same.
        let mut m = two_tori();
        m.triangles.remove(5);
        let nv = m.positions.len();
        let mut order: Vec<u32> = (0..nv as u32).collect();
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for i in (1..nv).rev() {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            order.swap(i, (state >> 33) as usize % (i + 1));
        }
        let mut shuffled = m.clone();
        for (old, &new) in order.iter().enumerate() {
            shuffled.positions[new as usize] = m.positions[old];
        }
        for t in &mut shuffled.triangles {
            *t = t.map(|v| order[v as usize]);
        }
        let (tiled, general) = both_paths(&shuffled);
        assert_eq!(tiled, None);
        assert_eq!(both_paths(&m).0, Some(general));
        assert_eq!(check(&shuffled), check(&m));
        assert_eq!(check(&m).boundary_edges, 3);
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
