//! Ray casting over a triangle BVH: orthographic cameras and the nearest triangle a ray hits.
//!
//! A [`Scene`] is an obvhs BVH over a mesh given as plain positions and triangles (no mesh
//! type, so the geometry crate can use it without a cycle). [`Camera`]s are orthographic:
//! parallel rays through a square window. [`Scene::cast`] returns the nearest hit along a
//! ray, with the index of the triangle in the caller's list. The preview pictures
//! (`sparc3d-render`) shade the hits; the rendering-based refinement of `sparcubes` reads
//! depth and normals from them. Nothing here draws or encodes pictures.
//!
//! Every result depends only on the scene and the ray: the BVH is built single-threaded and
//! the traversal order is fixed, so callers that cast rays in parallel get the same hits
//! whatever the thread count.
#![deny(missing_docs)]

mod camera;

pub use camera::{orbit_cameras, sphere_directions, Camera};
pub use obvhs::ray::Ray;

use glam::Vec3A;
use obvhs::bvh2::builder::build_bvh2_from_tris;
use obvhs::bvh2::Bvh2;
use obvhs::ray::RayHit;
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;
use std::time::Duration;

/// The nearest hit of a ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the ray (its direction is a unit vector).
    pub t: f32,
    /// Index of the triangle hit in the list the scene was built from.
    pub triangle: u32,
}

/// A mesh ready for ray casting: its triangles and a BVH over them.
pub struct Scene {
    /// Triangles with corners, in BVH build order of `ids`.
    triangles: Vec<Triangle>,
    /// Index in the caller's triangle list of each entry of `triangles`.
    ids: Vec<u32>,
    /// The BVH; `None` for a mesh without triangles.
    bvh: Option<Bvh2>,
}

impl Scene {
    /// Builds the BVH over the triangles of `positions` (single-threaded, deterministic).
    /// Triangles with an index out of range are skipped.
    pub fn new(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> Self {
        let p = positions;
        let mut ids = Vec::with_capacity(triangles.len());
        let mut tris = Vec::with_capacity(triangles.len());
        for (i, t) in triangles.iter().enumerate() {
            if t.iter().all(|&v| (v as usize) < p.len()) {
                ids.push(i as u32);
                tris.push(Triangle {
                    v0: Vec3A::from(p[t[0] as usize]),
                    v1: Vec3A::from(p[t[1] as usize]),
                    v2: Vec3A::from(p[t[2] as usize]),
                });
            }
        }
        let bvh = (!tris.is_empty()).then(|| {
            build_bvh2_from_tris(
                &tris,
                BvhBuildParams::medium_build(),
                &mut Duration::default(),
            )
        });
        Self {
            triangles: tris,
            ids,
            bvh,
        }
    }

    /// The nearest triangle along `ray`, or `None` on a miss.
    pub fn cast(&self, ray: Ray) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        let mut hit = RayHit::none();
        let found = bvh.ray_traverse(ray, &mut hit, |ray, id| {
            intersect(&self.triangles[bvh.primitive_indices[id] as usize], ray)
        });
        if !found {
            return None;
        }
        let k = bvh.primitive_indices[hit.primitive_id as usize] as usize;
        Some(Hit {
            t: hit.t,
            triangle: self.ids[k],
        })
    }
}

/// Distance along `ray` to `tri` (Möller–Trumbore), or infinity on a miss. Barycentric
/// coordinates down to `-1e-6` count as inside, so a ray through an edge shared by two
/// triangles hits one of them (no gaps along diagonals).
fn intersect(tri: &Triangle, ray: &Ray) -> f32 {
    const EPS: f32 = 1e-6;
    let e1 = tri.v1 - tri.v0;
    let e2 = tri.v2 - tri.v0;
    let p = ray.direction.cross(e2);
    let det = e1.dot(p);
    if det.abs() < f32::MIN_POSITIVE {
        return f32::INFINITY;
    }
    let inv = 1.0 / det;
    let s = ray.origin - tri.v0;
    let u = s.dot(p) * inv;
    let q = s.cross(e1);
    let v = ray.direction.dot(q) * inv;
    if u < -EPS || v < -EPS || u + v > 1.0 + EPS {
        return f32::INFINITY;
    }
    let t = e2.dot(q) * inv;
    if t >= ray.tmin && t <= ray.tmax {
        t
    } else {
        f32::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nearest_of_two_triangles_is_hit_with_its_own_index() {
        // Two squares' worth of triangles across the z axis at z = 1 and z = 3; a ray from z = 5
        // down hits the one at 3 first, and its index is the caller's (skipped ones included).
        let positions = [
            [-1.0, -1.0, 1.0],
            [1.0, -1.0, 1.0],
            [0.0, 1.0, 1.0],
            [-1.0, -1.0, 3.0],
            [1.0, -1.0, 3.0],
            [0.0, 1.0, 3.0],
        ];
        let triangles = [[0, 1, 2], [0, 1, 9], [3, 4, 5]];
        let scene = Scene::new(&positions, &triangles);
        let ray = Ray::new_inf(Vec3A::new(0.0, 0.0, 5.0), Vec3A::new(0.0, 0.0, -1.0));
        let hit = scene.cast(ray);
        assert_eq!(hit.map(|h| h.triangle), Some(2));
        assert!(hit.is_some_and(|h| (h.t - 2.0).abs() < 1e-6));
        let away = Ray::new_inf(Vec3A::new(5.0, 0.0, 5.0), Vec3A::new(0.0, 0.0, -1.0));
        assert_eq!(scene.cast(away), None);
        assert_eq!(Scene::new(&positions, &[]).cast(ray), None);
    }
}
