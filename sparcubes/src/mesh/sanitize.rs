//! Sanitising raw meshes: drop faces with out-of-range indices or non-finite corners.
//!
//! Loaders hand over whatever the file said; [`sanitize`] makes it a [`TriMesh`] that keeps
//! the type's invariants (every index in range, every used coordinate finite, no unused
//! vertex), and says what it dropped.

use crate::error::{Error, Result};
use crate::mesh::TriMesh;

/// What [`sanitize`] dropped.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SanitizeStats {
    /// Faces dropped because an index was out of range.
    pub faces_bad_index: u64,
    /// Faces dropped because a corner had a non-finite coordinate.
    pub faces_non_finite: u64,
    /// Vertices removed because no kept face used them.
    pub vertices_unused: u64,
}

/// Drops faces with an out-of-range index or a non-finite corner, then removes the vertices
/// no face uses (keeping the order of the others).
///
/// `context` names the source (a file name, or a description) in the error. Returns
/// [`Error::EmptyMesh`] when no triangle is left, with the counts of what was dropped.
pub fn sanitize(mesh: TriMesh, context: &str) -> Result<(TriMesh, SanitizeStats)> {
    let n = mesh.positions.len();
    let (mesh, stats) = drop_invalid(mesh);
    if mesh.triangles.is_empty() {
        return Err(Error::EmptyMesh {
            context: context.to_string(),
            reason: format!(
                "no valid triangle ({} vertices; dropped {} faces with an out-of-range index \
                 and {} with a non-finite coordinate)",
                n, stats.faces_bad_index, stats.faces_non_finite
            ),
        });
    }
    Ok((mesh, stats))
}

/// What [`sanitize`] does without judging the result: the mesh may be left with no triangle
/// (and then no vertex), for a caller that words that failure itself.
pub fn drop_invalid(mesh: TriMesh) -> (TriMesh, SanitizeStats) {
    let TriMesh {
        positions,
        triangles,
    } = mesh;
    let mut stats = SanitizeStats::default();
    let n = positions.len();
    let finite: Vec<bool> = positions
        .iter()
        .map(|p| p.iter().all(|c| c.is_finite()))
        .collect();

    let mut kept = Vec::with_capacity(triangles.len());
    for t in &triangles {
        if t.iter().any(|&i| i as usize >= n) {
            stats.faces_bad_index += 1;
        } else if t.iter().any(|&i| !finite[i as usize]) {
            stats.faces_non_finite += 1;
        } else {
            kept.push(*t);
        }
    }
    drop(triangles);

    // Compact: new index of every used vertex, in the original order.
    const UNUSED: u32 = u32::MAX;
    let mut remap = vec![UNUSED; n];
    for t in &kept {
        for &i in t {
            remap[i as usize] = 0;
        }
    }
    let mut new_positions = Vec::new();
    for (i, p) in positions.iter().enumerate() {
        if remap[i] != UNUSED {
            remap[i] = new_positions.len() as u32;
            new_positions.push(*p);
        }
    }
    stats.vertices_unused = (n - new_positions.len()) as u64;
    if stats.vertices_unused > 0 {
        for t in &mut kept {
            for i in t.iter_mut() {
                *i = remap[*i as usize];
            }
        }
    }
    (TriMesh::new(new_positions, kept), stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drops_bad_faces_and_unused_vertices() {
        let m = TriMesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [f32::NAN, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            vec![[0, 2, 3], [0, 1, 2], [0, 2, 9]],
        );
        let (m, s) = sanitize(m, "test").unwrap();
        assert_eq!(s.faces_bad_index, 1);
        assert_eq!(s.faces_non_finite, 1);
        assert_eq!(s.vertices_unused, 1);
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
        assert_eq!(m.positions.len(), 3);
    }

    #[test]
    fn nothing_left_is_an_error() {
        let m = TriMesh::new(vec![[0.0; 3]], vec![[0, 0, 5]]);
        let e = sanitize(m, "thing.obj").unwrap_err();
        assert!(matches!(e, Error::EmptyMesh { .. }));
        assert!(e.to_string().contains("thing.obj"));
    }
}
