//! Exact closest-point queries on a mesh's triangles, over `parry`'s bounding volume hierarchy.
//!
//! `parry` builds the hierarchy (binned SAH, one leaf per triangle, in `f64`) and runs the
//! best-first search ([`Bvh::find_best`]); the cost of a box is its squared distance to the
//! query and the cost of a triangle the squared distance to its closest point from
//! [`closest_on_triangle`], so distances are exactly those of that function and the search,
//! which prunes a box only when it is no nearer than the best triangle so far, finds the true
//! minimum. Of triangles at exactly the same distance (a shared corner, say) the first visited
//! is kept; its point and distance are the same whichever it is, and the sign of a closed
//! source (`weld::SignOracle`) is taken from the welded feature, so the results do not depend
//! on the order of the tree or on the thread count.

use super::geom::{closest_on_triangle, dist2, Feature, Vec3};
use super::sample::Faces;
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy, BvhLeafCost, BvhNode};

/// The closest point of a mesh to a query point.
#[derive(Debug, Clone, Copy)]
pub struct Closest {
    /// Index of the triangle it lies on.
    pub triangle: u32,
    /// The closest point.
    pub point: Vec3,
    /// Squared distance from the query.
    pub dist2: f64,
    /// Which feature of the triangle it lies on.
    pub feature: Feature,
}

impl BvhLeafCost for Closest {
    fn cost(&self) -> f64 {
        self.dist2
    }
}

/// A BVH over the triangles of a borrowed [`Faces`].
#[derive(Clone)]
pub struct TriBvh<'a> {
    /// The triangles.
    faces: &'a Faces,
    /// One leaf per triangle; a leaf's data is the triangle's index.
    bvh: Bvh,
}

impl<'a> TriBvh<'a> {
    /// Builds the hierarchy over all triangles of `faces`.
    pub fn new(faces: &'a Faces) -> Self {
        let boxes = faces.corners.iter().map(|[a, b, c]| {
            let lo = [0, 1, 2].map(|k| a[k].min(b[k]).min(c[k]));
            let hi = [0, 1, 2].map(|k| a[k].max(b[k]).max(c[k]));
            Aabb::new(Vector::from_array(lo), Vector::from_array(hi))
        });
        Self {
            faces,
            bvh: Bvh::from_iter(BvhBuildStrategy::Binned, boxes.enumerate()),
        }
    }

    /// The closest point of the mesh to `q`, or `None` when there is no triangle.
    pub fn closest(&self, q: Vec3) -> Option<Closest> {
        let box_cost = |node: &BvhNode, _best: f64| box_dist2(node, q);
        let triangle_cost = |t: u32, _best: f64| {
            let (point, feature) = closest_on_triangle(q, self.faces.corners.get(t as usize)?);
            Some(Closest {
                triangle: t,
                point,
                dist2: dist2(q, point),
                feature,
            })
        };
        self.bvh
            .find_best(f64::INFINITY, box_cost, triangle_cost)
            .map(|(_, closest)| closest)
    }
}

/// Squared distance from `q` to the box of `node` (0 inside).
fn box_dist2(node: &BvhNode, q: Vec3) -> f64 {
    let (lo, hi) = (node.mins().to_array(), node.maxs().to_array());
    (0..3)
        .map(|a| {
            let d = (lo[a] - q[a]).max(0.0).max(q[a] - hi[a]);
            d * d
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use sparcubes::shapes;

    /// Flat triangles of a torus and a sphere that cuts through it, in `f64`.
    fn faces() -> Faces {
        let mesh = shapes::merge(&[
            shapes::torus([0.0, 0.0, 0.0], 1.0, 0.3, 24),
            shapes::sphere([1.0, 0.0, 0.2], 0.4, 12),
        ]);
        let at = |i: u32| mesh.positions[i as usize].map(f64::from);
        Faces::new(
            mesh.triangles
                .iter()
                .map(|t| [at(t[0]), at(t[1]), at(t[2])])
                .collect(),
        )
    }

    /// The smallest squared distance from `q` to any triangle, by trying them all.
    fn brute_force(faces: &Faces, q: Vec3) -> f64 {
        faces
            .corners
            .iter()
            .map(|tri| dist2(q, closest_on_triangle(q, tri).0))
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn closest_is_the_exact_minimum_over_all_triangles() {
        let faces = faces();
        let bvh = TriBvh::new(&faces);
        // A lattice through, around and far outside both shapes, off the axes' symmetry.
        let mut checked = 0;
        for i in -6..=6 {
            for j in -6..=6 {
                for k in -4..=4 {
                    let q = [0.31 * i as f64, 0.29 * j as f64 + 0.013, 0.23 * k as f64];
                    let Some(c) = bvh.closest(q) else {
                        panic!("no closest point for {q:?}");
                    };
                    assert_eq!(c.dist2, brute_force(&faces, q), "query {q:?}");
                    let on = closest_on_triangle(q, &faces.corners[c.triangle as usize]);
                    assert_eq!((c.point, c.feature), on, "query {q:?}");
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 13 * 13 * 9);
    }

    #[test]
    fn no_triangle_no_closest_point() {
        let faces = Faces::new(Vec::new());
        assert!(TriBvh::new(&faces).closest([0.0, 0.0, 0.0]).is_none());
    }
}
