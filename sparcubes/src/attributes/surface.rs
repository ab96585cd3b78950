//! The source surface in the grid's frame, with the triangles that can carry a value.

use crate::cubes::SparseCubes;
use crate::materials::Appearance;
use crate::vec3::{cross, norm, sub};

/// The appearance's surface in grid coordinates: its corners, and the triangles whose
/// indices are in range, whose corners are finite and whose area is positive.
pub struct GridSurface<'a> {
    app: &'a Appearance,
    /// Corner positions in grid coordinates.
    pub positions: Vec<[f64; 3]>,
    /// (triangle index in the appearance, its area in grid units²), in the appearance's order.
    pub triangles: Vec<(usize, f64)>,
}

impl<'a> GridSurface<'a> {
    /// The surface of `app` placed in the grid of `cubes`.
    pub fn new(app: &'a Appearance, cubes: &SparseCubes) -> Self {
        let s = &app.surface;
        let n = cubes.resolution;
        let positions: Vec<[f64; 3]> = s
            .positions
            .iter()
            .map(|p| cubes.normalization.source_to_grid(p.map(f64::from), n))
            .collect();
        let triangles = s
            .triangles
            .iter()
            .enumerate()
            .filter_map(|(t, tri)| {
                let [Some(a), Some(b), Some(c)] = tri.map(|i| positions.get(i as usize).copied())
                else {
                    return None;
                };
                let area = norm(cross(sub(b, a), sub(c, a))) * 0.5;
                (area.is_finite() && area > 0.0).then_some((t, area))
            })
            .collect();
        Self {
            app,
            positions,
            triangles,
        }
    }

    /// The corners of the appearance's triangle `t` (one of [`Self::triangles`]).
    pub fn corners(&self, t: usize) -> [[f64; 3]; 3] {
        self.app.surface.triangles[t].map(|i| self.positions[i as usize])
    }

    /// The corner indices of the appearance's triangle `t`.
    pub fn indices(&self, t: usize) -> [u32; 3] {
        self.app.surface.triangles[t]
    }
}
