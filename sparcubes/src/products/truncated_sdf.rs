//! The truncated signed distance of the grid points near the surface: the points within
//! `truncation` voxels of the extracted mesh, each with its signed distance divided by the
//! truncation, so values lie in (−1, 1), positive outside.
//!
//! The distances are exact distances from each grid point to the extracted mesh (nearest-first
//! queries of [`crate::queries::closest`]'s tree, bounded by the truncation so that points
//! beyond it end early), and the sign comes from the sparse grid ([`crate::queries::sides`]).

use crate::grid::cubes::SparseCubes;
use crate::grid::{dilate, pack, BrickIndex, BrickSet, Dilation};
use crate::queries::closest::TriangleIndex;
use crate::queries::sides::GridSides;
use crate::stages::extract::extract;
use rayon::prelude::*;

/// The truncated signed distance of one item's grid points.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TruncatedSdf {
    /// Grid points (x, y, z) within the truncation band, sorted.
    pub coords: Vec<[u16; 3]>,
    /// Signed distance / truncation at each point, in (−1, 1), positive outside.
    pub sdf: Vec<f32>,
}

/// The truncated signed distance of `cubes` within `truncation` voxels of its surface.
pub fn truncated_sdf(cubes: &SparseCubes, truncation: f64) -> TruncatedSdf {
    let n = cubes.resolution;
    let mesh = extract(cubes);
    if mesh.triangles.is_empty() || truncation.is_nan() || truncation <= 0.0 {
        return TruncatedSdf::default();
    }
    let coords = band_vertices(cubes, truncation).sorted_members();
    let queries: Vec<[f64; 3]> = coords.par_iter().map(|c| c.map(f64::from)).collect();
    let nearest = TriangleIndex::new(&mesh).closest_batch_within(&queries, truncation);
    let sides = GridSides::new(cubes);
    let kept: Vec<([u16; 3], f32)> = coords
        .par_iter()
        .zip(&nearest)
        .map_init(Default::default, |scratch, (c, near)| {
            let udf = near.distance;
            if near.triangle == u32::MAX || udf >= truncation || c.iter().any(|&v| u32::from(v) > n)
            {
                return None;
            }
            let inside = sides.is_inside(c.map(f64::from), scratch);
            let s = if inside { -udf } else { udf } / truncation;
            Some((*c, s as f32))
        })
        .flatten()
        .collect();
    let (coords, sdf) = kept.into_iter().unzip();
    TruncatedSdf { coords, sdf }
}

/// Every grid point that can lie within `truncation` voxels of the surface: the corners of
/// the cells within `ceil(truncation)` cells of an active cell. A point within `t` of a
/// surface point of cell `c` is within `t` of the cell's box on every axis; the surface lies
/// in its active cells up to the deformation (under one voxel), so the point is a corner of
/// a cell at most `ceil(t)` cells from `c` along each axis.
pub fn band_vertices(cubes: &SparseCubes, truncation: f64) -> BrickSet {
    let n = cubes.resolution;
    let index = BrickIndex::for_resolution(n);
    let mut keys: Vec<u64> = cubes
        .cells
        .par_iter()
        .map(|c| pack(&index, c.map(u32::from)))
        .collect();
    keys.par_sort_unstable();
    let mut cells = BrickSet::from_sorted_packed(n, &keys);
    for _ in 0..truncation.ceil() as u32 {
        cells = dilate(&cells, n, Dilation::Box);
    }
    dilate(&cells, n, Dilation::Corners)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::Params;
    use crate::shapes::sphere;

    /// The band of the test, in voxels.
    const TRUNCATION: f64 = 4.0;

    #[test]
    fn band_of_a_sphere_holds_signed_scaled_distances() {
        // A sphere of radius 0.3 of the unit cube, centred: at resolution 40 its radius is
        // (40 − 6) · 0.3 voxels around the grid centre shifted by the normalization offset.
        let mesh = sphere([0.0; 3], 0.5, 48);
        let cubes = crate::convert(&mesh, &Params::with_resolution(40))
            .unwrap_or_else(|e| panic!("{e}"))
            .cubes;
        let s = truncated_sdf(&cubes, TRUNCATION);
        assert!(s.coords.len() > cubes.coords.len());
        assert!(s.coords.windows(2).all(|w| w[0] < w[1]));
        let centre = cubes.normalization.source_to_grid([0.0; 3], 40);
        let radius = 0.5 * cubes.normalization.scale * 40.0;
        let mut inside = 0;
        for (c, v) in s.coords.iter().zip(&s.sdf) {
            assert!(v.abs() < 1.0);
            let r = (0..3)
                .map(|a| (c[a] as f64 - centre[a]).powi(2))
                .sum::<f64>()
                .sqrt();
            // The faceted sphere and its marching-cubes surface lie within 0.2 voxel of it.
            assert!(
                ((r - radius) / TRUNCATION - *v as f64).abs() < 0.2 / TRUNCATION,
                "{c:?}"
            );
            inside += usize::from(*v < 0.0);
        }
        assert!(inside > 0 && inside < s.coords.len());
        // Every grid point within 3.5 voxels of the sphere is in the band.
        let lo = (centre[0] - radius - 4.0).floor() as u16;
        let hi = (centre[0] + radius + 4.0).ceil() as u16;
        for x in lo..=hi {
            let c = [x, centre[1].round() as u16, centre[2].round() as u16];
            let r = (0..3)
                .map(|a| (c[a] as f64 - centre[a]).powi(2))
                .sum::<f64>()
                .sqrt();
            if (r - radius).abs() < 3.5 {
                assert!(s.coords.binary_search(&c).is_ok(), "{c:?} missing");
            }
        }
    }
}
