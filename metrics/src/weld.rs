//! Welding, connected components, closedness and inside/outside sign of the source mesh.
//!
//! Vertices closer than a tolerance are welded (a hash grid with cells of the tolerance's
//! size: vertices in one cell are welded, and vertices of neighbouring cells when their cells'
//! first vertices are within the tolerance). Components are the triangle sets connected
//! through welded vertices. A mesh is closed when every edge of its non-degenerate triangles
//! is shared by exactly two triangles.

use super::geom::{add, dist2, dot, norm, scale, sub, Feature, Vec3};
use super::sample::Faces;
use super::tri_bvh::Closest;
use std::collections::HashMap;

/// Disjoint sets over `0..n`; every set's root is its smallest member, so the partition and
/// the roots do not depend on the order of the unions.
#[derive(Debug, Clone)]
struct UnionFind {
    /// Parent of each element; roots are their own parent.
    parent: Vec<u32>,
}

impl UnionFind {
    fn new(n: usize) -> Self {
        Self {
            parent: (0..n as u32).collect(),
        }
    }

    fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let up = self.parent[self.parent[x as usize] as usize];
            self.parent[x as usize] = up;
            x = up;
        }
        x
    }

    fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        let (lo, hi) = (ra.min(rb), ra.max(rb));
        self.parent[hi as usize] = lo;
    }
}

/// Welded vertex id per vertex: the smallest index of the vertices welded with it.
pub fn weld(positions: &[Vec3], tolerance: f64) -> Vec<u32> {
    let mut sets = UnionFind::new(positions.len());
    let cell_of = |p: Vec3| {
        if tolerance > 0.0 {
            p.map(|x| (x / tolerance).floor() as i64)
        } else {
            p.map(|x| x.to_bits() as i64)
        }
    };
    let mut cells: HashMap<[i64; 3], u32> = HashMap::with_capacity(positions.len());
    for (i, &p) in positions.iter().enumerate() {
        match cells.entry(cell_of(p)) {
            std::collections::hash_map::Entry::Occupied(e) => sets.union(*e.get(), i as u32),
            std::collections::hash_map::Entry::Vacant(e) => {
                e.insert(i as u32);
            }
        }
    }
    if tolerance > 0.0 {
        let tol2 = tolerance * tolerance;
        for (cell, &first) in &cells {
            for n in neighbours(*cell) {
                if let Some(&other) = cells.get(&n) {
                    if dist2(positions[first as usize], positions[other as usize]) <= tol2 {
                        sets.union(first, other);
                    }
                }
            }
        }
    }
    (0..positions.len() as u32).map(|i| sets.find(i)).collect()
}

/// The 26 cells around `c`.
fn neighbours(c: [i64; 3]) -> impl Iterator<Item = [i64; 3]> {
    (0..27)
        .filter(|&k| k != 13)
        .map(move |k| [c[0] + k % 3 - 1, c[1] + (k / 3) % 3 - 1, c[2] + k / 9 - 1])
}

/// Connected components of triangles through welded vertices: a component index per
/// triangle (numbered in order of first appearance) and the number of components.
pub fn components(triangles: &[[u32; 3]], welded: &[u32]) -> (Vec<u32>, usize) {
    let mut sets = UnionFind::new(welded.len());
    for t in triangles {
        let [a, b, c] = t.map(|i| welded[i as usize]);
        sets.union(a, b);
        sets.union(a, c);
    }
    let mut label: HashMap<u32, u32> = HashMap::new();
    let per_triangle = triangles
        .iter()
        .map(|t| {
            let root = sets.find(welded[t[0] as usize]);
            let next = label.len() as u32;
            *label.entry(root).or_insert(next)
        })
        .collect();
    (per_triangle, label.len())
}

/// Undirected edges `(key, triangle, corner)` of the non-degenerate welded triangles, sorted
/// by key; the key packs the two welded vertex ids, smaller first.
fn sorted_edges(triangles: &[[u32; 3]], welded: &[u32]) -> Vec<(u64, u32, u8)> {
    let mut edges = Vec::with_capacity(triangles.len() * 3);
    for (t, tri) in triangles.iter().enumerate() {
        let w = tri.map(|i| welded[i as usize]);
        if w[0] == w[1] || w[1] == w[2] || w[0] == w[2] {
            continue;
        }
        for k in 0..3 {
            edges.push((edge_key(w[k], w[(k + 1) % 3]), t as u32, k as u8));
        }
    }
    edges.sort_unstable();
    edges
}

/// Key of the undirected edge between welded vertices `a` and `b`.
fn edge_key(a: u32, b: u32) -> u64 {
    ((a.min(b) as u64) << 32) | a.max(b) as u64
}

/// Whether every edge of the non-degenerate welded triangles is shared by exactly two
/// triangles (and there is at least one such triangle).
pub fn is_closed(triangles: &[[u32; 3]], welded: &[u32]) -> bool {
    let edges = sorted_edges(triangles, welded);
    !edges.is_empty() && edges.chunk_by(|a, b| a.0 == b.0).all(|run| run.len() == 2)
}

/// Inside/outside sign of points near a closed, consistently oriented mesh, from angle-weighted
/// pseudo-normals (Bærentzen & Aanæs 2005): the normal of the face, edge or corner that the
/// closest point lies on.
#[derive(Debug, Clone)]
pub struct SignOracle {
    /// Welded vertex id of each corner, three per triangle.
    corners: Vec<[u32; 3]>,
    /// Angle-weighted normal per welded vertex id.
    vertex_normals: Vec<Vec3>,
    /// Sum of the face normals of the triangles around each edge, sorted by edge key.
    edge_normals: Vec<(u64, Vec3)>,
    /// +1 when the mesh is oriented outwards (positive signed volume), −1 otherwise.
    orientation: f64,
}

impl SignOracle {
    /// Builds the pseudo-normals of `faces`, whose corners are `triangles` over `welded` ids.
    pub fn new(faces: &Faces, triangles: &[[u32; 3]], welded: &[u32]) -> Self {
        let corners: Vec<[u32; 3]> = triangles
            .iter()
            .map(|t| t.map(|i| welded[i as usize]))
            .collect();
        let mut vertex_normals = vec![[0.0; 3]; welded.len()];
        let mut volume = 0.0;
        for (t, ids) in corners.iter().enumerate() {
            let p = &faces.corners[t];
            let n = faces.normals[t];
            volume += dot(p[0], super::geom::cross(p[1], p[2]));
            for k in 0..3 {
                let u = sub(p[(k + 1) % 3], p[k]);
                let v = sub(p[(k + 2) % 3], p[k]);
                let angle = (dot(u, v) / (norm(u) * norm(v))).clamp(-1.0, 1.0).acos();
                if angle.is_finite() {
                    let slot = &mut vertex_normals[ids[k] as usize];
                    *slot = add(*slot, scale(n, angle));
                }
            }
        }
        let edge_normals = sorted_edges(triangles, welded)
            .chunk_by(|a, b| a.0 == b.0)
            .map(|run| {
                let sum = run
                    .iter()
                    .fold([0.0; 3], |s, &(_, t, _)| add(s, faces.normals[t as usize]));
                (run[0].0, sum)
            })
            .collect();
        Self {
            corners,
            vertex_normals,
            edge_normals,
            orientation: if volume < 0.0 { -1.0 } else { 1.0 },
        }
    }

    /// +1 when `q` is outside the mesh, −1 inside, given its closest point on the mesh.
    pub fn sign(&self, q: Vec3, closest: &Closest, faces: &Faces) -> f64 {
        let t = closest.triangle as usize;
        let ids = self.corners[t];
        let normal = match closest.feature {
            Feature::Face => faces.normals[t],
            Feature::Corner(k) => self.vertex_normals[ids[k as usize] as usize],
            Feature::Edge(k) => {
                let key = edge_key(ids[k as usize], ids[(k as usize + 1) % 3]);
                match self.edge_normals.binary_search_by_key(&key, |e| e.0) {
                    Ok(i) => self.edge_normals[i].1,
                    Err(_) => faces.normals[t],
                }
            }
        };
        if dot(sub(q, closest.point), normal) * self.orientation < 0.0 {
            -1.0
        } else {
            1.0
        }
    }
}
