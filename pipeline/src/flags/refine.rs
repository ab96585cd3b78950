//! `--refine` and its settings: the rendering-based refinement of the displacements
//! (docs/ALGORITHM.md §12), off by default.

use sparcubes::refine::RefineParams;

/// Whether to refine the displacements against renderings of the source (paper step 4), and
/// with which settings; each setting left out takes its default (docs/ALGORITHM.md §12).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct RefineArgs {
    /// Refine the displacements against depth and normal renderings of the source (off by
    /// default; docs/QUALITY.md has its measured gain, docs/PERFORMANCE.md its cost).
    #[arg(long)]
    pub refine: bool,
    /// Views of the refinement, spread evenly over the sphere (default 12, at most 64).
    #[arg(long, requires = "refine", value_name = "N")]
    pub refine_views: Option<u32>,
    /// Side of each view's picture in pixels (default 3 × the resolution within [384, 2048], at
    /// most 2048).
    #[arg(long, requires = "refine", value_name = "PIXELS")]
    pub refine_image: Option<u32>,
    /// Optimiser (Adam) steps (default 12, at most 200).
    #[arg(long, requires = "refine", value_name = "N")]
    pub refine_steps: Option<u32>,
    /// Adam's step size in voxels (default 0.015, in (0, 0.45]).
    #[arg(long, requires = "refine", value_name = "VOXELS")]
    pub refine_rate: Option<f32>,
}

impl RefineArgs {
    /// The settings the flags ask for; `None` without `--refine`.
    pub fn settings(&self) -> Option<RefineParams> {
        if !self.refine {
            return None;
        }
        let d = RefineParams::default();
        Some(RefineParams {
            views: self.refine_views.unwrap_or(d.views),
            image: self.refine_image.or(d.image),
            steps: self.refine_steps.unwrap_or(d.steps),
            rate: self.refine_rate.unwrap_or(d.rate),
        })
    }
}
