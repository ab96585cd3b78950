//! The settings of the refinement (`[params] refine`), their defaults and ranges.

use crate::error::{Error, Result};
use serde::{Deserialize, Deserializer, Serialize};

/// Most views a refinement may render.
pub const MAX_VIEWS: u32 = 64;
/// Largest picture side, pixels: a view of 2048² targets takes about 80 MB.
pub const MAX_IMAGE: u32 = 2048;
/// Most optimiser steps.
pub const MAX_STEPS: u32 = 200;

/// Settings of the rendering-based refinement (docs/ALGORITHM.md §7b). Stored whole in a job's
/// config when the refinement is on, so a job keeps the settings it was made with.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RefineParams {
    /// Orthographic views, their directions spread evenly over the sphere (Fibonacci lattice).
    pub views: u32,
    /// Side of each square picture, pixels.
    pub image: u32,
    /// Adam steps.
    pub steps: u32,
    /// Adam's step size, voxels.
    pub rate: f32,
}

/// The defaults: on a CAD mesh of the dev corpus at 256³ (`chassis.STL`), 12 views of 384²
/// (about 1.3 voxels a pixel) and 12 steps of 0.015 voxel gave the normal consistency of 16
/// views of 512² and 20 steps in half the time; steps of 0.05 lowered it (Adam moves every
/// seen vertex by about the step size, noise included). docs/QUALITY.md, "Refinement".
impl Default for RefineParams {
    fn default() -> Self {
        Self {
            views: 12,
            image: 384,
            steps: 12,
            rate: 0.015,
        }
    }
}

impl RefineParams {
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
        if !(8..=MAX_IMAGE).contains(&self.image) {
            return bad("image", format!("8..={MAX_IMAGE}"), self.image.to_string());
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
