//! Stage 12 (paper step 4, optional): the displacements refined against renderings of the
//! source.
//!
//! Sparc3D's Sparcubes refines the deformed grid by rendering (Sparc3D, §3.2, step 4): depth
//! and normal images I_D, I_N of the input from a set of cameras, the mesh M of the current
//! φ/δ rendered from the same cameras, and gradient descent on
//! L = ‖R_D(M) − I_D‖² + ‖R_N(M) − I_N‖² over the vertex displacements. Here:
//!
//! - the cameras are [`views`]: `views` orthographic pictures of `image²` pixels from
//!   directions spread over the sphere, framing the normalised object;
//! - the targets are the source's exact depth and facing normal per pixel;
//! - M is [`Surface`]: with φ fixed every output vertex is a fixed weighted sum of displaced
//!   corners, so positions, and the gradient back to δ, are exact;
//! - the loss of a pixel and its gradient on the hit triangle's corners are [`pixel`]'s;
//! - Adam ([`adam`]) moves δ, each component kept within ±`Params::deform_max` (below half a
//!   voxel: no cell inverts), φ is not touched, so the signs, the topology and the watertight
//!   guarantee are those of the unrefined grid.
//!
//! Only what a camera sees is refined: a vertex no compared pixel pulls on keeps the
//! displacement it had (step 3's, or none), as do thin-shell vertices (their surface is an
//! offset of an open sheet by design, not the source). If the loss rises for
//! [`DIVERGED_AFTER`] evaluations in a row the refinement stops; in every case the
//! displacements kept are those of the lowest loss seen.

pub mod adam;
pub mod pixel;
pub mod settings;
pub mod surface;
pub mod views;

pub use settings::RefineParams;
pub use surface::Surface;

use crate::grid::cubes::SparseCubes;
use crate::mesh::GridMesh;
use adam::Adam;
use serde::Serialize;
use views::{hits, targets, view_loss, Targets, Traced, View};

/// Evaluations of a rising loss in a row after which the refinement stops.
pub const DIVERGED_AFTER: u32 = 3;

/// How a refinement ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Ran its steps; the best iterate is kept.
    Finished,
    /// The loss rose for [`DIVERGED_AFTER`] evaluations in a row; the best iterate is kept.
    Diverged,
    /// No camera compares any pixel of the output with the source: nothing was refined.
    NothingVisible,
    /// Every active vertex is held (all of them in thin shells): nothing was rendered.
    NothingFree,
}

/// What one refinement did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RefineStats {
    /// How it ended.
    pub outcome: Outcome,
    /// Optimiser steps taken.
    pub steps: u32,
    /// The loss before refining (mean over the source's pixels of all views).
    pub loss_first: f64,
    /// The lowest loss seen, whose displacements are kept.
    pub loss_best: f64,
    /// The step that gave it (0: the unrefined grid).
    pub best_step: u32,
    /// Source pixels compared with the output (not capped), before refining.
    pub compared_pixels: u64,
    /// Active vertices whose displacement the refinement changed.
    pub moved_vertices: u64,
}

/// The loss of the surface at `delta` over all views, the pixels compared, and the gradient
/// on the surface's vertices.
fn evaluate(
    surface: &Surface,
    cubes: &SparseCubes,
    delta: &[[f64; 3]],
    views: &[View],
    targets: &[Targets],
) -> (f64, u64, Vec<[f64; 3]>) {
    let positions = surface.positions(cubes, delta);
    let traced = Traced::new(&positions, &surface.triangles);
    let mut grad = vec![[0.0; 3]; positions.len()];
    let (mut loss, mut compared) = (0.0, 0);
    for (view, target) in views.iter().zip(targets) {
        let h = hits(&traced, view, target);
        let (l, c) = view_loss(&traced, &surface.triangles, view, target, &h, &mut grad);
        loss += l;
        compared += c;
    }
    (loss, compared, grad)
}

/// The bounding box of `mesh`'s vertices.
fn bounds(mesh: &GridMesh) -> ([f64; 3], [f64; 3]) {
    let mut b = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in &mesh.verts {
        for a in 0..3 {
            b.0[a] = b.0[a].min(p[a]);
            b.1[a] = b.1[a].max(p[a]);
        }
    }
    b
}

/// Refines `cubes.deformation` against renderings of `source` (in grid coordinates, as the
/// conversion sees it). `free[i]` says whether active vertex `i` may move; each component
/// stays within ±`bound` voxels.
pub fn refine(
    cubes: &mut SparseCubes,
    source: &GridMesh,
    free: &[bool],
    settings: &RefineParams,
    bound: f32,
) -> RefineStats {
    let mut stats = RefineStats {
        outcome: Outcome::NothingFree,
        steps: 0,
        loss_first: 0.0,
        loss_best: 0.0,
        best_step: 0,
        compared_pixels: 0,
        moved_vertices: 0,
    };
    if !free.iter().take(cubes.coords.len()).any(|&f| f) {
        return stats;
    }
    stats.outcome = Outcome::Finished;
    stats.loss_best = f64::INFINITY;
    let surface = Surface::new(cubes);
    let image = settings.image_for(cubes.resolution);
    let views = views::views(bounds(source), settings.views, image);
    let targets: Vec<Targets> = {
        let traced = Traced::new(&source.verts, &source.tris);
        views.iter().map(|v| targets(&traced, v)).collect()
    };
    let pixels = targets
        .iter()
        .flatten()
        .filter(|t| t.is_some())
        .count()
        .max(1) as f64;
    let start: Vec<[f64; 3]> = cubes.deformation.iter().map(|d| d.map(f64::from)).collect();
    let mut delta = start.clone();
    let mut adam = Adam::new(delta.len());
    let (mut best, mut previous, mut rising) = (start.clone(), f64::INFINITY, 0);
    for step in 0..=settings.steps {
        let (loss, compared, grad) = evaluate(&surface, cubes, &delta, &views, &targets);
        let loss = loss / pixels;
        if step == 0 {
            stats.loss_first = loss;
            stats.compared_pixels = compared;
            if compared == 0 {
                stats.outcome = Outcome::NothingVisible;
                stats.loss_best = loss;
                return stats;
            }
        }
        if loss < stats.loss_best {
            (stats.loss_best, stats.best_step) = (loss, step);
            best.clone_from(&delta);
        }
        rising = if loss > previous { rising + 1 } else { 0 };
        previous = loss;
        if rising >= DIVERGED_AFTER {
            stats.outcome = Outcome::Diverged;
            break;
        }
        if step == settings.steps {
            break;
        }
        let mut g = surface.pull_back(&grad, delta.len());
        for (i, g) in g.iter_mut().enumerate() {
            let free = free.get(i).copied().unwrap_or(false);
            *g = if free {
                g.map(|c| c / pixels)
            } else {
                [0.0; 3]
            };
        }
        adam.step(&mut delta, &g, settings.rate as f64, bound as f64);
        stats.steps += 1;
    }
    for ((d, b), s) in cubes.deformation.iter_mut().zip(&best).zip(&start) {
        if b != s {
            *d = b.map(|c| c as f32);
            stats.moved_vertices += 1;
        }
    }
    stats
}

#[cfg(test)]
mod tests;
