//! Sharp edges of a mesh: edges shared by exactly two triangles whose normals differ by at
//! least a given angle (the vector-set consumers' rule, which selects Blender's "sharp" edges
//! by dihedral angle; their sources in docs/FORMAT.md, "Samples for vector-set VAEs"), and
//! length-uniform points on them.

use super::rng::Draw;
use crate::mesh::TriMesh;
use crate::vec3::{add, dot, norm, scale, sub, Vec3};
use rayon::prelude::*;

/// The sharp edges of a mesh, with a cumulative length table for sampling.
#[derive(Debug, Clone, Default)]
pub struct SharpEdges {
    /// First end of each edge.
    pub a: Vec<Vec3>,
    /// Second end of each edge.
    pub b: Vec<Vec3>,
    /// Unit mean of the two face normals of each edge.
    pub normals: Vec<Vec3>,
    /// Dihedral angle of each edge: the angle between its two face normals, in degrees.
    pub angles: Vec<f64>,
    /// Running sum of the edge lengths.
    cumulative: Vec<f64>,
}

impl SharpEdges {
    /// Number of sharp edges.
    pub fn len(&self) -> usize {
        self.a.len()
    }

    /// Whether there is no sharp edge.
    pub fn is_empty(&self) -> bool {
        self.a.is_empty()
    }

    /// A point uniform by length over the edges and its edge's normal, from numbers 0 and 1.
    pub fn draw(&self, d: &Draw) -> (Vec3, Vec3) {
        let total = self.cumulative.last().copied().unwrap_or(0.0);
        let target = d.uniform(0) * total;
        let i = self
            .cumulative
            .partition_point(|&c| c <= target)
            .min(self.a.len() - 1);
        let t = d.uniform(1);
        (
            add(self.a[i], scale(sub(self.b[i], self.a[i]), t)),
            self.normals[i],
        )
    }
}

/// The edges of `mesh` shared by exactly two triangles of positive area whose unit normals
/// make an angle of at least `angle_deg` degrees, in order of their (lower, higher) vertex
/// numbers.
pub fn sharp_edges(mesh: &TriMesh, angle_deg: f64) -> SharpEdges {
    // (lower vertex, higher vertex, triangle) for every triangle side, sorted.
    let mut sides: Vec<(u32, u32, u32)> = mesh
        .triangles
        .par_iter()
        .enumerate()
        .flat_map_iter(|(t, tri)| {
            (0..3).map(move |k| {
                let (u, v) = (tri[k], tri[(k + 1) % 3]);
                (u.min(v), u.max(v), t as u32)
            })
        })
        .collect();
    sides.par_sort_unstable();
    let unit = |t: u32| -> Option<Vec3> {
        let n = mesh.face_normal(t as usize);
        let l = norm(n);
        (l > 0.0 && l.is_finite()).then(|| scale(n, 1.0 / l))
    };
    let cos_limit = angle_deg.to_radians().cos();
    let mut out = SharpEdges::default();
    let mut total = 0.0;
    let mut i = 0;
    while i < sides.len() {
        let mut j = i + 1;
        while j < sides.len() && sides[j].0 == sides[i].0 && sides[j].1 == sides[i].1 {
            j += 1;
        }
        if j - i == 2 {
            if let (Some(n1), Some(n2)) = (unit(sides[i].2), unit(sides[i + 1].2)) {
                let c = dot(n1, n2).clamp(-1.0, 1.0);
                let mean = add(n1, n2);
                let ml = norm(mean);
                if c <= cos_limit && ml > 1e-12 {
                    let p = |v: u32| mesh.positions[v as usize].map(f64::from);
                    let (a, b) = (p(sides[i].0), p(sides[i].1));
                    total += norm(sub(b, a));
                    out.a.push(a);
                    out.b.push(b);
                    out.normals.push(scale(mean, 1.0 / ml));
                    out.angles.push(c.acos().to_degrees());
                    out.cumulative.push(total);
                }
            }
        }
        i = j;
    }
    out
}
