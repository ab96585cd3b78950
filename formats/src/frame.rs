//! Frames of exported points: the job's normalized frame, where samples are drawn
//! (`p = 2·g/N − 1`, the grid cube onto [−1, 1]³, the object's longest side spanning
//! `2·(N − 2·margin)/N` around a centre a fraction of a voxel off the origin,
//! [`sparcubes::normalize::GRID_OFFSET`]), the source mesh's frame, and each consumer's own
//! cube. Every map between them is a similarity (`q = p·factor + offset`), so points move
//! exactly and distances scale by `factor`; nothing is resampled.

use sparcubes::normalize::{Normalization, GRID_OFFSET};

/// The frame an export's points are written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Frame {
    /// The consumer's own cube (its normalization of the object), the default.
    Consumer,
    /// The job's normalized frame, [−1, 1]³ over the grid cube.
    Normalized,
    /// The source mesh's frame (as `convert` and `show` write meshes).
    Source,
}

impl Frame {
    /// Every frame, in the order of `--frame`'s values.
    pub const ALL: [Frame; 3] = [Frame::Consumer, Frame::Normalized, Frame::Source];

    /// The name `--frame` takes.
    pub fn name(self) -> &'static str {
        match self {
            Frame::Consumer => "consumer",
            Frame::Normalized => "normalized",
            Frame::Source => "source",
        }
    }
}

/// A similarity from the job's normalized frame: `q = p·factor + offset`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// Scale of points and of distances.
    pub factor: f64,
    /// Translation after scaling.
    pub offset: [f64; 3],
}

impl Placement {
    /// The normalized frame itself.
    pub const IDENTITY: Placement = Placement {
        factor: 1.0,
        offset: [0.0; 3],
    };

    /// Normalized → source: `p = 2·(source − center)·scale`, so `source = p/(2·scale) + center`.
    pub fn to_source(norm: &Normalization) -> Placement {
        Placement {
            factor: 1.0 / (2.0 * norm.scale),
            offset: norm.center,
        }
    }

    /// Normalized → a cube where the object's bounding box is centred on the origin and its
    /// longest side spans `[−half_extent, half_extent]` (what a consumer's
    /// `normalize_mesh` does to a mesh), for a job at `resolution` whose object's longest
    /// side spans `span` of the grid (`sparcubes::Params::span`).
    pub fn centred(resolution: u32, span: f64, half_extent: f64) -> Placement {
        let n = resolution as f64;
        // The fitted box's longest side spans `span` of the unit cube, i.e. that half extent
        // in the normalized frame, around 2·GRID_OFFSET/N (normalize.rs, `fit_span`).
        let factor = half_extent / span;
        Placement {
            factor,
            offset: GRID_OFFSET.map(|o| -2.0 * o / n * factor),
        }
    }

    /// Normalized → the grid's coordinates in voxels (`g = (p / 2 + 0.5) · N`,
    /// `sparcubes::Normalization`): the frame of exports that write grid indices
    /// (Direct3D-S2's `sparse_index`, cubvh's cells).
    pub fn grid(resolution: u32) -> Placement {
        let half = resolution as f64 / 2.0;
        Placement {
            factor: half,
            offset: [half; 3],
        }
    }

    /// A point moved into the frame.
    #[inline]
    pub fn point(&self, p: [f32; 3]) -> [f64; 3] {
        std::array::from_fn(|a| p[a] as f64 * self.factor + self.offset[a])
    }

    /// A distance scaled into the frame.
    #[inline]
    pub fn distance(&self, d: f32) -> f64 {
        d as f64 * self.factor
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centred_puts_a_fitted_box_on_the_consumers_cube() {
        // A box fitted by the job's normalization lands, in the consumer's frame, centred on
        // the origin with its longest side spanning ±half_extent.
        let (lo, hi) = ([-3.0, 1.0, 2.0], [5.0, 2.0, 4.0]);
        for (n, margin) in [(64u32, 3u32), (256, 3), (512, 8)] {
            let norm = Normalization::fit((lo, hi), n, margin);
            let to_norm = |s: [f64; 3]| -> [f32; 3] {
                let g = norm.source_to_grid(s, n);
                g.map(|c| (2.0 * c / n as f64 - 1.0) as f32)
            };
            let span = (n - 2 * margin) as f64 / n as f64;
            let place = Placement::centred(n, span, 0.9999);
            let (a, b) = (place.point(to_norm(lo)), place.point(to_norm(hi)));
            assert!(
                (a[0] + 0.9999).abs() < 1e-6 && (b[0] - 0.9999).abs() < 1e-6,
                "{a:?} {b:?}"
            );
            for axis in 1..3 {
                assert!(
                    (a[axis] + b[axis]).abs() < 1e-6,
                    "not centred on {axis}: {a:?} {b:?}"
                );
            }
            // And back to the source frame through the other placement.
            let src = Placement::to_source(&norm).point(to_norm(hi));
            assert!((0..3).all(|k| (src[k] - hi[k]).abs() < 1e-5), "{src:?}");
        }
    }
}
