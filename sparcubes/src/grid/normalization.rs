//! The map between the source frame and the grid (fitted by stage 1, `normalize`, and used
//! by everyone who reads the output back in the source frame). Grid
//! coordinates are in voxels: the grid spans `[0, N]³`, the unit cube `[-0.5, 0.5]³` maps onto
//! it, and the mesh's bounding box is centred with `margin_cells` free cells on each side of
//! its longest extent. Also the extents a mesh may have to be converted at all.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// Smallest longest side of a mesh's bounding box that is converted, in source units. Input
/// coordinates are `f32`: a mesh smaller than this lives among the subnormal and
/// barely-normal numbers (below about 1e-38 `f32` keeps fewer than 24 bits, down to none at
/// 1.4e-45), where the vertices no longer say where the surface is and a conversion would
/// be silently wrong. 1e-15 keeps squared lengths (1e-30) far above that range; no real mesh
/// in any unit (a nanometre model in metres is 1e-9 across) comes near it.
pub const MIN_EXTENT: f64 = 1e-15;

/// Largest longest side of a mesh's bounding box that is converted, in source units: squared
/// lengths (1e30) stay far below `f32::MAX` (3.4e38), and the output, written back in the
/// source frame as `f32`, stays finite.
pub const MAX_EXTENT: f64 = 1e15;

/// Refuses a mesh whose bounding box's longest side is outside [`MIN_EXTENT`, `MAX_EXTENT`]
/// (a mesh smaller than the minimum is [`Error::EmptyMesh`]: nothing measurable is left, like a
/// mesh of zero area; a larger one [`Error::TooLarge`]).
pub fn check_extent(bounds: ([f64; 3], [f64; 3]), context: &str) -> Result<()> {
    let (lo, hi) = bounds;
    let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0f64, f64::max);
    if extent < MIN_EXTENT {
        return Err(Error::EmptyMesh {
            context: context.to_string(),
            reason: format!(
                "the mesh is {extent:e} across, below the smallest extent converted \
                 ({MIN_EXTENT:e} source units): too small to be resolved in single precision"
            ),
        });
    }
    if extent > MAX_EXTENT {
        return Err(Error::TooLarge {
            context: context.to_string(),
            reason: format!(
                "the mesh is {extent:e} across, above the largest extent converted \
                 ({MAX_EXTENT:e} source units)"
            ),
        });
    }
    Ok(())
}

/// Sub-voxel shift of the grid against the mesh, per axis: (√2−1)/16, (√3−1)/20, (√5−2)/13.
pub const GRID_OFFSET: [f64; 3] = [
    0.025_888_347_648_318,
    0.036_602_540_378_444,
    0.018_155_785_765_794,
];

/// The affine map between the source frame and the unit cube: `unit = (p − center) · scale`.
/// Grid coordinates are `g = (unit + 0.5) · N`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Normalization {
    /// Centre of the source mesh's bounding box.
    pub center: [f64; 3],
    /// Factor from source units to unit-cube units.
    pub scale: f64,
}

/// The identity: no shift, scale 1.
impl Default for Normalization {
    fn default() -> Self {
        Self {
            center: [0.0; 3],
            scale: 1.0,
        }
    }
}

impl Normalization {
    /// The normalization that centres `bounds` and fits its longest side into
    /// `(N − 2·margin) / N` of the unit cube. A degenerate (flat or point) box keeps scale
    /// finite by treating its longest side as at least 1e-12 of the coordinates' magnitude.
    pub fn fit(bounds: ([f64; 3], [f64; 3]), resolution: u32, margin_cells: u32) -> Self {
        let usable = (resolution - 2 * margin_cells) as f64 / resolution as f64;
        Self::fit_span(bounds, resolution, usable)
    }

    /// The normalization that centres `bounds` and fits its longest side into `span` of the
    /// unit cube (`span · N` cells; [`crate::Params::span`]), as [`Normalization::fit`].
    pub fn fit_span(bounds: ([f64; 3], [f64; 3]), resolution: u32, span: f64) -> Self {
        let (lo, hi) = bounds;
        let center = [
            0.5 * (lo[0] + hi[0]),
            0.5 * (lo[1] + hi[1]),
            0.5 * (lo[2] + hi[2]),
        ];
        let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0f64, f64::max);
        let magnitude = (0..3)
            .map(|a| lo[a].abs().max(hi[a].abs()))
            .fold(1e-30, f64::max);
        let extent = extent.max(magnitude * 1e-12);
        let scale = span / extent;
        // Shift by a small, different irrational fraction of a voxel per axis, so that the
        // axis-aligned and diagonal faces common in real meshes (at "round" coordinates) never
        // lie exactly on grid planes or through grid vertices, where every predicate of the
        // later stages would be degenerate.
        let center =
            std::array::from_fn(|a| center[a] - GRID_OFFSET[a] / (scale * resolution as f64));
        Self { center, scale }
    }

    /// Source point → grid coordinates (voxels) at resolution `n`.
    #[inline]
    pub fn source_to_grid(&self, p: [f64; 3], n: u32) -> [f64; 3] {
        let n = n as f64;
        [
            ((p[0] - self.center[0]) * self.scale + 0.5) * n,
            ((p[1] - self.center[1]) * self.scale + 0.5) * n,
            ((p[2] - self.center[2]) * self.scale + 0.5) * n,
        ]
    }

    /// Grid coordinates (voxels) at resolution `n` → source point.
    #[inline]
    pub fn grid_to_source(&self, g: [f64; 3], n: u32) -> [f64; 3] {
        let n = n as f64;
        [
            (g[0] / n - 0.5) / self.scale + self.center[0],
            (g[1] / n - 0.5) / self.scale + self.center[1],
            (g[2] / n - 0.5) / self.scale + self.center[2],
        ]
    }
}
