//! The extracted mesh as a linear function of the displacements.
//!
//! With φ fixed, a marching-cubes vertex on a cell edge is `(1 − w)·pa + w·pb` with the edge's
//! weight `w = φa/(φa − φb)` ([`crate::extract()`]'s `edge_point`) and `p = coord + δ` at either
//! corner, and a centre vertex is the mean of some edge vertices: every output position is a
//! fixed weighted sum of corner positions. [`Surface`] keeps those weights (its stencils), so
//! positions follow δ exactly and a gradient on positions goes back to δ through the same
//! weights.

use crate::grid::cubes::SparseCubes;
use crate::stages::extract::mc_table::{self, CENTRE, EDGES};
use crate::stages::extract::{centres_used, for_each_case};
use std::collections::HashMap;

/// The mesh [`crate::extract()`] gives for some cubes, with each vertex as a weighted sum of
/// active vertices.
#[derive(Debug, Clone, Default)]
pub struct Surface {
    /// Start of each vertex's stencil in `terms` (one more entry than vertices).
    starts: Vec<u32>,
    /// (active vertex, weight) pairs; a vertex's weights sum to 1.
    terms: Vec<(u32, f64)>,
    /// Triangles over the vertices, oriented as [`crate::extract()`]'s.
    pub triangles: Vec<[u32; 3]>,
}

/// The weight of corner b on cube edge `(a, b)` with corner values `sa`, `sb`, as the
/// extraction computes it.
fn edge_weight(sa: f32, sb: f32) -> f64 {
    let (sa, sb) = (sa as f64, sb as f64);
    let w = sa / (sa - sb);
    if w.is_finite() {
        w.clamp(0.0, 1.0)
    } else {
        0.5
    }
}

impl Surface {
    /// The surface of `cubes` (the same triangles, positions and orientation as
    /// [`crate::extract()`], its vertices numbered in order of first use).
    pub fn new(cubes: &SparseCubes) -> Self {
        let n = cubes.coords.len().min(cubes.sdf.len());
        let table = mc_table::table();
        let mut s = Self {
            starts: vec![0],
            ..Self::default()
        };
        let mut edges: HashMap<usize, u32> = HashMap::new();
        for_each_case(cubes, n, &cubes.cells, |idx, mask, bits| {
            let case = table.case(mask, bits);
            let mut edge = |e: u8, s: &mut Self| -> u32 {
                let (a, b, axis) = EDGES[e as usize];
                let (ia, ib) = (idx[a as usize], idx[b as usize]);
                *edges.entry(ia * 3 + axis as usize).or_insert_with(|| {
                    let w = edge_weight(cubes.sdf[ia], cubes.sdf[ib]);
                    s.push(&[(ia as u32, 1.0 - w), (ib as u32, w)])
                })
            };
            let used = centres_used(case);
            let mut centres = [u32::MAX; 16];
            for (k, list) in case.centres.iter().enumerate() {
                if used >> k & 1 == 1 {
                    let mut stencil = Vec::with_capacity(2 * list.len());
                    let m = list.len() as f64;
                    for &e in list {
                        let (a, b, _) = EDGES[e as usize];
                        let (ia, ib) = (idx[a as usize], idx[b as usize]);
                        let w = edge_weight(cubes.sdf[ia], cubes.sdf[ib]);
                        stencil.push((ia as u32, (1.0 - w) / m));
                        stencil.push((ib as u32, w / m));
                    }
                    centres[k] = s.push(&stencil);
                }
            }
            for tri in &case.triangles {
                let ids = tri.map(|v| {
                    if v < CENTRE {
                        edge(v, &mut s)
                    } else {
                        centres[(v - CENTRE) as usize]
                    }
                });
                s.triangles.push(ids);
            }
        });
        s
    }

    /// Appends a vertex with `stencil`; returns its number.
    fn push(&mut self, stencil: &[(u32, f64)]) -> u32 {
        self.terms.extend_from_slice(stencil);
        self.starts.push(self.terms.len() as u32);
        (self.starts.len() - 2) as u32
    }

    /// Vertices of the surface.
    pub fn vertex_count(&self) -> usize {
        self.starts.len() - 1
    }

    /// The stencil of vertex `v`: (active vertex, weight) pairs.
    pub fn stencil(&self, v: usize) -> &[(u32, f64)] {
        &self.terms[self.starts[v] as usize..self.starts[v + 1] as usize]
    }

    /// Vertex positions (voxels) for the displacements `delta` of the active vertices.
    pub fn positions(&self, cubes: &SparseCubes, delta: &[[f64; 3]]) -> Vec<[f64; 3]> {
        use rayon::prelude::*;
        (0..self.vertex_count())
            .into_par_iter()
            .map(|v| {
                let mut p = [0.0; 3];
                for &(i, w) in self.stencil(v) {
                    let (c, d) = (cubes.coords[i as usize], delta[i as usize]);
                    for a in 0..3 {
                        p[a] += w * (c[a] as f64 + d[a]);
                    }
                }
                p
            })
            .collect()
    }

    /// The gradient on the displacements from a gradient on vertex positions (the stencils
    /// transposed), summed in vertex order.
    pub fn pull_back(&self, grad: &[[f64; 3]], active: usize) -> Vec<[f64; 3]> {
        let mut out = vec![[0.0; 3]; active];
        for (v, g) in grad.iter().enumerate() {
            for &(i, w) in self.stencil(v) {
                let o = &mut out[i as usize];
                for a in 0..3 {
                    o[a] += w * g[a];
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stages::extract::{extract, sample_box};

    #[test]
    fn positions_are_those_of_the_extracted_mesh() {
        // A ball with a displacement field: the surface's triangles carry the same corners,
        // within f32 rounding, as extract's (which numbers its vertices differently).
        let cubes = sample_box(16, [0; 3], [16; 3], |c| {
            let p = c.map(|v| v as f32 - 8.0);
            let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            (r - 5.3, [0.1 * p[1].sin(), -0.2 * p[0].cos(), 0.05])
        });
        let delta: Vec<[f64; 3]> = cubes.deformation.iter().map(|d| d.map(f64::from)).collect();
        let s = Surface::new(&cubes);
        let p = s.positions(&cubes, &delta);
        let mesh = extract(&cubes);
        assert_eq!(s.triangles.len(), mesh.triangles.len());
        // Each triangle turned to start at its smallest corner (orientation kept), sorted.
        let sorted = |tris: Vec<[[f64; 3]; 3]>| {
            let mut tris: Vec<[[f64; 3]; 3]> = tris
                .into_iter()
                .map(|t| {
                    let first = (0..3)
                        .min_by(|&i, &j| {
                            t[i].partial_cmp(&t[j]).unwrap_or(std::cmp::Ordering::Equal)
                        })
                        .unwrap_or(0);
                    std::array::from_fn(|k| t[(first + k) % 3])
                })
                .collect();
            tris.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
            tris
        };
        let ours = sorted(
            s.triangles
                .iter()
                .map(|t| t.map(|v| p[v as usize]))
                .collect(),
        );
        let theirs = sorted(
            mesh.triangles
                .iter()
                .map(|t| t.map(|v| mesh.positions[v as usize].map(f64::from)))
                .collect(),
        );
        for (a, b) in ours.iter().zip(&theirs) {
            for k in 0..3 {
                for c in 0..3 {
                    assert!((a[k][c] - b[k][c]).abs() < 1e-5, "{a:?} vs {b:?}");
                }
            }
        }
    }
}
