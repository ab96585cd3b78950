//! The settings of the refinement (`[params] refine`), their defaults and ranges.

use crate::error::{Error, Result};
use serde::{Deserialize, Deserializer, Serialize};

/// Most views a refinement may render.
pub const MAX_VIEWS: u32 = 64;
/// Largest picture side, pixels: a view of 2048² targets takes about 80 MB.
pub const MAX_IMAGE: u32 = 2048;
/// Most optimiser steps.
pub const MAX_STEPS: u32 = 200;

/// Settings of the rendering-based refinement (docs/ALGORITHM.md §12). Stored whole in a job's
/// config when the refinement is on, so a job keeps the settings it was made with.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RefineParams {
    /// Orthographic views, their directions spread evenly over the sphere (Fibonacci lattice).
    pub views: u32,
    /// Side of each square picture, pixels; `None` (the default): [`auto_image`] of the
    /// grid's resolution.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub image: Option<u32>,
    /// Adam steps.
    pub steps: u32,
    /// Adam's step size, voxels.
    pub rate: f32,
}

/// Smallest picture side the automatic size gives.
pub const AUTO_IMAGE_MIN: u32 = 384;

/// The picture side for a grid of `resolution`³ when none is set: 3 pixels per cell across
/// the grid (a pixel about 0.6 voxel, since a view frames the bounding sphere), at least
/// [`AUTO_IMAGE_MIN`] and at most [`MAX_IMAGE`]. Measured on the dev corpus's CAD-like meshes
/// (docs/QUALITY.md, "Refinement against renderings"): with 384² pictures the refinement gains
/// at 64³–256³ but lowers the normal consistency at 512³ (a pixel 2.4 voxels there); 1536²
/// at 512³ turns that into a gain.
pub fn auto_image(resolution: u32) -> u32 {
    resolution
        .saturating_mul(3)
        .clamp(AUTO_IMAGE_MIN, MAX_IMAGE)
}

/// The defaults: on a CAD mesh of the dev corpus at 256³ (`chassis.STL`), 12 views and 12
/// steps of 0.015 voxel gave the normal consistency of 16 views and 20 steps in half the time;
/// steps of 0.05 lowered it (Adam moves every seen vertex by about the step size, noise
/// included). The picture size follows the resolution ([`auto_image`]). docs/QUALITY.md,
/// "Refinement".
impl Default for RefineParams {
    fn default() -> Self {
        Self {
            views: 12,
            image: None,
            steps: 12,
            rate: 0.015,
        }
    }
}

impl RefineParams {
    /// The picture side used at `resolution`: the one set, else [`auto_image`].
    pub fn image_for(&self, resolution: u32) -> u32 {
        self.image.unwrap_or_else(|| auto_image(resolution))
    }

    /// Checks each setting's range; the error names the key (`refine.views`, …).
    pub fn validate(&self) -> Result<()> {
        let bad = |key: &str, range: String, got: String| {
            Err(Error::InvalidParams(format!(
                "refine.{key} must be in {range}, got {got}"
            )))
        };
        if !(1..=MAX_VIEWS).contains(&self.views) {
            return bad("views", format!("1..={MAX_VIEWS}"), self.views.to_string());
        }
        if let Some(image) = self.image.filter(|i| !(8..=MAX_IMAGE).contains(i)) {
            return bad("image", format!("8..={MAX_IMAGE}"), image.to_string());
        }
        if self.steps > MAX_STEPS {
            return bad("steps", format!("0..={MAX_STEPS}"), self.steps.to_string());
        }
        if !(self.rate > 0.0 && self.rate <= 0.45) {
            return bad("rate", "(0, 0.45] voxel".into(), self.rate.to_string());
        }
        Ok(())
    }
}

/// `refine` as a job file writes it: `true` (the default settings), `false`, or a table of
/// settings (missing ones take their defaults).
#[derive(Deserialize)]
#[serde(untagged)]
enum Written {
    On(bool),
    Settings(RefineParams),
}

/// Reads [`crate::Params::refine`]: a missing key, `null` or `false` is off, `true` the
/// default settings, a table its settings.
pub fn deserialize<'de, D: Deserializer<'de>>(
    d: D,
) -> std::result::Result<Option<RefineParams>, D::Error> {
    Ok(match Option::<Written>::deserialize(d)? {
        None | Some(Written::On(false)) => None,
        Some(Written::On(true)) => Some(RefineParams::default()),
        Some(Written::Settings(s)) => Some(s),
    })
}
