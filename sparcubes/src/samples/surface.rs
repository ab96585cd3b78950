//! Area-uniform points on a mesh: a cumulative area table over the triangles of positive
//! area, searched with one uniform number, and a uniform point inside the chosen triangle.

use super::rng::Draw;
use crate::mesh::TriMesh;
use crate::vec3::{norm, scale};

/// Cumulative areas of the triangles of positive area, in triangle order.
#[derive(Debug, Clone)]
pub struct AreaTable {
    /// Running sum of the areas (summed in triangle order, so it is reproducible).
    cumulative: Vec<f64>,
    /// The triangle of each entry.
    triangles: Vec<u32>,
}

impl AreaTable {
    /// The table of `mesh`.
    pub fn new(mesh: &TriMesh) -> Self {
        let mut cumulative = Vec::with_capacity(mesh.triangles.len());
        let mut triangles = Vec::with_capacity(mesh.triangles.len());
        let mut total = 0.0;
        for t in 0..mesh.triangles.len() {
            let a = 0.5 * norm(mesh.face_normal(t));
            if a > 0.0 && a.is_finite() {
                total += a;
                cumulative.push(total);
                triangles.push(t as u32);
            }
        }
        Self {
            cumulative,
            triangles,
        }
    }

    /// Whether the mesh has no triangle of positive area.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// A point uniform by area and the unit normal of its triangle, from numbers
    /// `k..k + 3` of `d`.
    pub fn draw(&self, mesh: &TriMesh, d: &Draw, k: u64) -> ([f64; 3], [f64; 3]) {
        let total = self.cumulative.last().copied().unwrap_or(0.0);
        let target = d.uniform(k) * total;
        let i = self
            .cumulative
            .partition_point(|&c| c <= target)
            .min(self.triangles.len() - 1);
        let t = self.triangles[i] as usize;
        let [a, b, c] = mesh.triangle(t);
        let r = d.uniform(k + 1).sqrt();
        let s = d.uniform(k + 2);
        let (wa, wb, wc) = (1.0 - r, r * (1.0 - s), r * s);
        let p = std::array::from_fn(|x| wa * a[x] + wb * b[x] + wc * c[x]);
        let n = mesh.face_normal(t);
        (p, scale(n, 1.0 / norm(n)))
    }
}
