//! The triangle mesh every stage works on: a flat struct of arrays.

/// An indexed triangle mesh. Invariants (after [`crate::mesh::sanitize`]): every index is
/// `< positions.len()` and every coordinate is finite.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Triangles as indices into `positions`, counter-clockwise seen from outside when the
    /// mesh is oriented.
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Builds a mesh from positions and triangles.
    pub fn new(positions: Vec<[f32; 3]>, triangles: Vec<[u32; 3]>) -> Self {
        Self {
            positions,
            triangles,
        }
    }

    /// Number of triangles.
    pub fn face_count(&self) -> usize {
        self.triangles.len()
    }

    /// Axis-aligned bounds `(min, max)` of the vertices used by triangles, or `None` when there
    /// is no triangle.
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for t in &self.triangles {
            for &i in t {
                let p = self.positions[i as usize];
                for a in 0..3 {
                    lo[a] = lo[a].min(p[a] as f64);
                    hi[a] = hi[a].max(p[a] as f64);
                }
            }
        }
        (!self.triangles.is_empty()).then_some((lo, hi))
    }

    /// Corner positions of triangle `t` in double precision.
    #[inline]
    pub fn triangle(&self, t: usize) -> [[f64; 3]; 3] {
        let [a, b, c] = self.triangles[t];
        let p = |i: u32| {
            let q = self.positions[i as usize];
            [q[0] as f64, q[1] as f64, q[2] as f64]
        };
        [p(a), p(b), p(c)]
    }

    /// Cross product of triangle `t`'s edges: along its normal (counter-clockwise winding),
    /// with length twice its area.
    #[inline]
    pub fn face_normal(&self, t: usize) -> [f64; 3] {
        let [a, b, c] = self.triangle(t);
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ]
    }

    /// Total surface area.
    pub fn area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| {
                let n = self.face_normal(t);
                0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
            })
            .sum()
    }

    /// Signed volume (positive for a closed mesh oriented outwards).
    pub fn signed_volume(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.triangle(t);
                crate::vec3::dot(a, crate::vec3::cross(b, c)) / 6.0
            })
            .sum()
    }
}
