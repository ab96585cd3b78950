//! The mesh as the conversion's stages see it: in grid coordinates (voxels), in double
//! precision, without zero-area triangles (stage 1 makes it).

/// The input mesh in grid coordinates (voxels), double precision.
#[derive(Debug, Clone, Default)]
pub struct GridMesh {
    /// Vertex positions in voxels.
    pub verts: Vec<[f64; 3]>,
    /// Triangles (indices into `verts`).
    pub tris: Vec<[u32; 3]>,
}

impl GridMesh {
    /// Corners of triangle `t`.
    #[inline]
    pub fn tri(&self, t: usize) -> [[f64; 3]; 3] {
        let [a, b, c] = self.tris[t];
        [
            self.verts[a as usize],
            self.verts[b as usize],
            self.verts[c as usize],
        ]
    }
}
