//! Point samples for vector-set VAEs (3DShape2VecSet, Dora, Hunyuan3D-2.x, TripoSG,
//! Step1X-3D), drawn from the watertight output mesh of one item:
//!
//! - **surface**: points uniform by area, with the unit normal of their triangle;
//! - **sharp**: points uniform by length on the edges whose dihedral angle is at least
//!   `sharp_angle_deg`, with the normalised mean of the two face normals (Dora's edge normal,
//!   `sharp_edge_sampling/sharp_sample.py`);
//! - **near**: area-uniform surface points moved by a truncated normal offset per axis
//!   (σ cycling through `near_sigmas`), with their signed distance;
//! - **volume**: points uniform in `[-volume_bound, volume_bound]³`, with their signed
//!   distance and occupancy.
//!
//! Everything is in the job's **normalized frame**: the grid cube `[0, N]³` mapped onto
//! `[-1, 1]³` (`p = 2·g/N − 1`, so `p = 2·(source − center)·scale`). Distances are exact
//! distances to the extracted mesh ([`crate::closest`]); their sign, negative inside, comes
//! from the closest triangle's face where the closest point lies strictly inside it
//! ([`TriangleIndex::face_side`], exact for the closed output mesh of the sparse grid), else
//! from the sparse grid ([`crate::sides`]). Before the grid sides set aside crossings that
//! graze a triangle's border, the two differed on about one near point in 2000
//! (storage-rounded points on the grid's dyadic planes, where the grid's crossing count met a
//! triangle edge), and there the face was right by the winding number (docs/PERFORMANCE.md,
//! issue 13 section); now they agree (tests). Query points are rounded to the storage
//! precision first, so a stored point and its stored distance belong together; a distance
//! too small for the precision keeps its sign as the smallest subnormal.
//!
//! Every random number is drawn from `(seed, kind, sample index)` ([`rng`]), so the samples
//! are the same whatever the thread count. [`farthest_points`] picks the farthest-point
//! subset that Dora's files hold from drawn points.

mod fps;
pub mod rng;
mod sharp;
mod surface;

use crate::closest::TriangleIndex;
use crate::cubes::SparseCubes;
use crate::error::{Error, Result};
use crate::mesh::TriMesh;
use crate::sides::GridSides;
use rayon::prelude::*;
use rng::Draw;
use serde::{Deserialize, Serialize};
pub use fps::farthest_points;
pub use sharp::sharp_edges;
use surface::AreaTable;

/// Most samples of one kind per item (16 Mi): 16 Mi points of `f32` are 192 MiB.
pub const MAX_PER_KIND: usize = 1 << 24;

/// Storage precision of sample coordinates, normals and distances.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// IEEE half precision (`<f2`), as Hunyuan3D-2.1's `watertight_and_sample.py` stores.
    F16,
    /// IEEE single precision (`<f4`), as Dora's and Step1X-3D's loaders read.
    F32,
}

impl Precision {
    /// `x` rounded to this precision (round to nearest even).
    #[inline]
    pub fn round(self, x: f64) -> f64 {
        match self {
            Precision::F16 => half::f16::from_f64(x).to_f64(),
            Precision::F32 => x as f32 as f64,
        }
    }

    /// A signed distance rounded to this precision, keeping its side: a magnitude that rounds
    /// to zero becomes the smallest positive subnormal with the distance's sign.
    #[inline]
    pub fn round_signed(self, magnitude: f64, inside: bool) -> f64 {
        let mut r = self.round(magnitude);
        if r == 0.0 {
            r = match self {
                Precision::F16 => half::f16::from_bits(1).to_f64(),
                Precision::F32 => f32::from_bits(1) as f64,
            };
        }
        if inside {
            -r
        } else {
            r
        }
    }
}

/// How many samples of each kind, and how they are drawn. The defaults follow Hunyuan3D-2.1's
/// `hy3dshape/tools/watertight/watertight_and_sample.py`: 499712 / 4 = 124928 surface and
/// sharp-edge points, twice as many near points with truncated normal offsets σ = 0.005 and
/// 0.05 (truncated at ±0.25), twice the sharp count of volume points in [−1.05, 1.05]³,
/// `f16` storage; the sharp-edge angle is Dora's 15° (`sharp_edge_sampling/README.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SampleParams {
    /// Area-uniform surface points.
    pub surface: usize,
    /// Points on sharp edges.
    pub sharp: usize,
    /// Points near the surface, with signed distance.
    pub near: usize,
    /// Points uniform in the volume, with signed distance and occupancy.
    pub volume: usize,
    /// Standard deviations of the near points' offsets (normalized units), used in turn.
    pub near_sigmas: Vec<f64>,
    /// Largest offset per axis of a near point (normalized units).
    pub near_bound: f64,
    /// Half the side of the volume sampling cube (normalized units).
    pub volume_bound: f64,
    /// Smallest dihedral angle of a sharp edge, in degrees.
    pub sharp_angle_deg: f64,
    /// Storage precision (`"f16"` or `"f32"`).
    pub dtype: Precision,
    /// Seed of every random number.
    pub seed: u64,
}

impl Default for SampleParams {
    fn default() -> Self {
        Self {
            surface: 124_928,
            sharp: 124_928,
            near: 249_856,
            volume: 249_856,
            near_sigmas: vec![0.005, 0.05],
            near_bound: 0.25,
            volume_bound: 1.05,
            sharp_angle_deg: 15.0,
            dtype: Precision::F16,
            seed: 0,
        }
    }
}

impl SampleParams {
    /// Checks every field; the error names the key (`samples.<field>`).
    pub fn validate(&self) -> Result<()> {
        let bad =
            |key: &str, why: String| Err(Error::InvalidParams(format!("samples.{key}: {why}")));
        for (key, n) in [
            ("surface", self.surface),
            ("sharp", self.sharp),
            ("near", self.near),
            ("volume", self.volume),
        ] {
            if n > MAX_PER_KIND {
                return bad(
                    key,
                    format!(
                        "{n} samples per item would not fit in memory (at most {MAX_PER_KIND})"
                    ),
                );
            }
        }
        if self.near > 0 && self.near_sigmas.is_empty() {
            return bad(
                "near_sigmas",
                "needs at least one value when near > 0".into(),
            );
        }
        if let Some(s) = self
            .near_sigmas
            .iter()
            .find(|s| !(s.is_finite() && **s > 0.0))
        {
            return bad("near_sigmas", format!("{s} is not a positive number"));
        }
        if !(self.near_bound.is_finite() && self.near_bound > 0.0) {
            return bad(
                "near_bound",
                format!("{} is not a positive number", self.near_bound),
            );
        }
        if !(self.volume_bound.is_finite() && self.volume_bound > 0.0) {
            return bad(
                "volume_bound",
                format!("{} is not a positive number", self.volume_bound),
            );
        }
        if !(0.0..=180.0).contains(&self.sharp_angle_deg) {
            return bad(
                "sharp_angle_deg",
                format!("{} is not in [0, 180]", self.sharp_angle_deg),
            );
        }
        Ok(())
    }
}

/// The samples of one item, in the normalized frame, rounded to the storage precision.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Samples {
    /// Surface points.
    pub surface_points: Vec<[f32; 3]>,
    /// Unit normal of each surface point's triangle.
    pub surface_normals: Vec<[f32; 3]>,
    /// Points on sharp edges (empty when the mesh has no sharp edge).
    pub sharp_points: Vec<[f32; 3]>,
    /// Edge normal of each sharp point.
    pub sharp_normals: Vec<[f32; 3]>,
    /// Near-surface points.
    pub near_points: Vec<[f32; 3]>,
    /// Signed distance of each near point to the surface (negative inside).
    pub near_sdf: Vec<f32>,
    /// Volume points.
    pub volume_points: Vec<[f32; 3]>,
    /// Signed distance of each volume point (negative inside).
    pub volume_sdf: Vec<f32>,
    /// 1 when the volume point is inside, else 0.
    pub volume_occupancy: Vec<u8>,
    /// Sharp edges found on the mesh (not searched, 0, when no sharp sample is asked for).
    pub sharp_edges: u64,
}

/// Stream numbers of the kinds (each kind draws its own numbers).
const SURFACE: u64 = 1;
const SHARP: u64 = 2;
const NEAR: u64 = 3;
const VOLUME: u64 = 4;

/// Draws the samples of `params` from `mesh`, the mesh that [`crate::extract`] made of
/// `cubes` (grid coordinates). Fails on invalid parameters and on an empty mesh when any
/// sample is asked for.
pub fn sample(cubes: &SparseCubes, mesh: &TriMesh, params: &SampleParams) -> Result<Samples> {
    params.validate()?;
    let n = cubes.resolution as f64;
    let to_norm = |g: [f64; 3]| g.map(|c| 2.0 * c / n - 1.0);
    let to_grid = |p: [f64; 3]| p.map(|c| (c + 1.0) * 0.5 * n);
    let prec = params.dtype;
    let round3 = |p: [f64; 3]| p.map(|c| prec.round(c));
    let store = |p: [f64; 3]| p.map(|c| c as f32);
    let wanted = params.surface + params.sharp + params.near + params.volume;
    if wanted == 0 {
        return Ok(Samples::default());
    }
    let areas = AreaTable::new(mesh);
    if areas.is_empty() {
        return Err(Error::EmptyMesh {
            context: "samples".into(),
            reason: "the extracted mesh has no triangle of positive area".into(),
        });
    }
    let mut out = Samples::default();

    // Surface: area-uniform points with their face normal.
    (out.surface_points, out.surface_normals) = areas
        .draw_batch(mesh, (params.seed, SURFACE), params.surface, |_, _, s| {
            (store(round3(to_norm(s.point))), store(round3(s.normal)))
        })
        .into_iter()
        .unzip();

    // Sharp edges.
    let edges = if params.sharp > 0 {
        sharp_edges(mesh, params.sharp_angle_deg)
    } else {
        Default::default()
    };
    out.sharp_edges = edges.len() as u64;
    if !edges.is_empty() {
        (out.sharp_points, out.sharp_normals) = (0..params.sharp as u64)
            .into_par_iter()
            .map(|i| {
                let (p, normal) = edges.draw(&Draw::new(params.seed, SHARP, i));
                (store(round3(to_norm(p))), store(round3(normal)))
            })
            .unzip();
    }

    // Near and volume points: positions first (rounded), then exact distances and sides.
    let sigmas = &params.near_sigmas;
    let near: Vec<[f64; 3]> =
        areas.draw_batch(mesh, (params.seed, NEAR), params.near, |i, d, s| {
            let sigma = sigmas[(i % sigmas.len() as u64) as usize];
            let p = to_norm(s.point);
            let offset: [f64; 3] = d.truncated_normals(8, sigma, params.near_bound);
            round3(std::array::from_fn(|a| p[a] + offset[a]))
        });
    let b = params.volume_bound;
    let volume: Vec<[f64; 3]> = (0..params.volume as u64)
        .into_par_iter()
        .map(|i| {
            let d = Draw::new(params.seed, VOLUME, i);
            round3(std::array::from_fn(|a| {
                b * (2.0 * d.uniform(a as u64) - 1.0)
            }))
        })
        .collect();
    if !near.is_empty() || !volume.is_empty() {
        let index = TriangleIndex::new(mesh);
        // The grid sides, built only when some point's closest triangle does not give its side.
        let sides = std::sync::OnceLock::new();
        let signed = |points: &[[f64; 3]]| -> (Vec<f32>, Vec<bool>) {
            let grid: Vec<[f64; 3]> = points.par_iter().map(|&p| to_grid(p)).collect();
            let closest = index.closest_batch(&grid);
            let inside = face_or_grid_sides(&index, &grid, &closest, || {
                sides.get_or_init(|| GridSides::new(cubes))
            });
            let sdf = closest
                .par_iter()
                .zip(&inside)
                .map(|(c, &ins)| prec.round_signed(c.distance * 2.0 / n, ins) as f32)
                .collect();
            (sdf, inside)
        };
        let (near_sdf, _) = signed(&near);
        let (volume_sdf, inside) = signed(&volume);
        out.near_points = near.into_iter().map(store).collect();
        out.near_sdf = near_sdf;
        out.volume_points = volume.into_iter().map(store).collect();
        out.volume_sdf = volume_sdf;
        out.volume_occupancy = inside.into_iter().map(u8::from).collect();
    }
    Ok(out)
}

/// Whether each point (grid coordinates) is inside: from its closest triangle where
/// [`TriangleIndex::face_side`] gives it (most near points), else from the grid sides. The face
/// is cheaper than the grid's local parity test (module docs).
fn face_or_grid_sides<'a>(
    index: &TriangleIndex,
    grid: &[[f64; 3]],
    closest: &[crate::closest::ClosestPoint],
    sides: impl FnOnce() -> &'a GridSides<'a>,
) -> Vec<bool> {
    let face: Vec<Option<bool>> = grid
        .par_iter()
        .zip(closest)
        .map(|(&g, c)| index.face_side(g, c))
        .collect();
    let rest: Vec<[f64; 3]> = grid
        .iter()
        .zip(&face)
        .filter(|(_, f)| f.is_none())
        .map(|(&g, _)| g)
        .collect();
    if rest.is_empty() {
        return face.into_iter().map(|f| f == Some(true)).collect();
    }
    let mut rest = sides().inside_batch(&rest).into_iter();
    face.into_iter()
        .map(|f| f.unwrap_or_else(|| rest.next().unwrap_or(false)))
        .collect()
}

#[cfg(test)]
mod tests;
