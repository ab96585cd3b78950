//! The cameras of the refinement, the source's target images, and the loss of the current
//! surface over every view with its gradient on the surface's vertices.
//!
//! Orthographic cameras look at the centre of the normalised object from directions spread
//! evenly over the sphere ([`sparc3d_raycast::sphere_directions`]); each picture frames the
//! object's bounding sphere. Rays are cast only for pixels where the source is seen (the
//! targets), and the output's BVH, which lies in the active cells, turns the rest away at its
//! root box. Rows are traced in parallel; each row's loss and per-pixel gradients are kept
//! apart and summed in view, row and pixel order, so the result is the same bytes whatever the
//! thread count.

use super::pixel::{depth_normal, pixel_loss, PixelRay, Target, CAPPED_LOSS};
use rayon::prelude::*;
use sparc3d_raycast::{sphere_directions, Camera, Scene};

/// A view: its camera and picture size.
#[derive(Debug, Clone, Copy)]
pub struct View {
    /// The orthographic camera, in voxels.
    pub camera: Camera,
    /// Side of the square picture, pixels.
    pub size: u32,
}

impl View {
    /// The ray of pixel (`x`, `y`) in double precision.
    fn ray(&self, x: u32, y: u32) -> PixelRay {
        let r = self.camera.ray(x, y, self.size);
        PixelRay {
            origin: r.origin.to_array().map(f64::from),
            dir: r.direction.to_array().map(f64::from),
        }
    }
}

/// `count` views of `size` pixels framing the box `bounds` (voxels).
pub fn views(bounds: ([f64; 3], [f64; 3]), count: u32, size: u32) -> Vec<View> {
    let (lo, hi) = bounds;
    let center = std::array::from_fn(|a| ((lo[a] + hi[a]) * 0.5) as f32);
    let radius = (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt() * 0.5;
    let half = (radius * 1.05).max(1.0) as f32;
    sphere_directions(count)
        .into_iter()
        .map(|d| View {
            camera: Camera::looking(center, d.map(|c| -c as f32), half),
            size,
        })
        .collect()
}

/// A mesh to trace: f64 corners per triangle and its BVH.
pub struct Traced {
    /// Corners of each triangle, voxels.
    corners: Vec<[[f64; 3]; 3]>,
    /// The BVH over them (f32).
    scene: Scene,
}

impl Traced {
    /// The mesh of `positions` and `triangles`.
    pub fn new(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> Self {
        let p32: Vec<[f32; 3]> = positions.iter().map(|p| p.map(|c| c as f32)).collect();
        Self {
            corners: triangles
                .iter()
                .map(|t| t.map(|v| positions[v as usize]))
                .collect(),
            scene: Scene::new(&p32, triangles),
        }
    }

    /// The triangle seen at pixel (`x`, `y`) of `view`, if any.
    fn hit(&self, view: &View, x: u32, y: u32) -> Option<u32> {
        self.scene
            .cast(view.camera.ray(x, y, view.size))
            .map(|h| h.triangle)
    }
}

/// What the source shows in one view: a target per pixel, row by row (`None`: background).
pub type Targets = Vec<Option<Target>>;

/// The source's picture in `view`: exact depth and facing normal of the triangle each pixel's
/// ray hits first.
pub fn targets(source: &Traced, view: &View) -> Targets {
    let size = view.size;
    (0..size * size)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % size, i / size);
            let t = source.hit(view, x, y)?;
            let (depth, normal) = depth_normal(&view.ray(x, y), &source.corners[t as usize])?;
            Some(Target {
                depth: depth as f32,
                normal: normal.map(|c| c as f32),
            })
        })
        .collect()
}

/// The triangles the output shows at each pixel where the source is seen (`u32::MAX`: none).
pub fn hits(output: &Traced, view: &View, targets: &Targets) -> Vec<u32> {
    let size = view.size;
    targets
        .par_iter()
        .enumerate()
        .map(|(i, t)| {
            let (x, y) = (i as u32 % size, i as u32 / size);
            t.and_then(|_| output.hit(view, x, y)).unwrap_or(u32::MAX)
        })
        .collect()
}

/// The loss of one view summed over its target pixels, the number of pixels compared (not
/// capped), and the gradient on each vertex of `triangles` added into `grad` in pixel order.
pub fn view_loss(
    output: &Traced,
    triangles: &[[u32; 3]],
    view: &View,
    targets: &Targets,
    hits: &[u32],
    grad: &mut [[f64; 3]],
) -> (f64, u64) {
    let size = view.size as usize;
    // Per row: its loss, compared pixels and (triangle, corner gradients) in pixel order.
    type Row = (f64, u64, Vec<(u32, [[f64; 3]; 3])>);
    let rows: Vec<Row> = (0..size)
        .into_par_iter()
        .map(|y| {
            let mut row: Row = (0.0, 0, Vec::new());
            for x in 0..size {
                let i = y * size + x;
                let Some(target) = targets[i] else { continue };
                let t = hits[i];
                if t == u32::MAX {
                    row.0 += CAPPED_LOSS;
                    continue;
                }
                let ray = view.ray(x as u32, y as u32);
                let (loss, g) = pixel_loss(&ray, &output.corners[t as usize], &target);
                row.0 += loss;
                if loss < CAPPED_LOSS {
                    row.1 += 1;
                    row.2.push((t, g));
                }
            }
            row
        })
        .collect();
    let (mut loss, mut compared) = (0.0, 0);
    for (l, c, pixels) in rows {
        loss += l;
        compared += c;
        for (t, g) in pixels {
            for (k, &v) in triangles[t as usize].iter().enumerate() {
                for a in 0..3 {
                    grad[v as usize][a] += g[k][a];
                }
            }
        }
    }
    (loss, compared)
}
