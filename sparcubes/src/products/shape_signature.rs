//! A shape signature of the watertight output: a fixed-length vector that two copies of one
//! shape share whatever rigid motion, uniform scale, mirroring or triangulation separates
//! them, so that near-duplicates are close in plain Euclidean distance ([`distance`]).
//!
//! It is read from the surface of the extracted mesh (never the source's triangle list, so a
//! re-triangulated source gives the same output up to the grid's rounding), through
//! [`SURFACE_POINTS`] points taken at equal steps of area along the triangles (systematic
//! sampling: no random draw, and the output's triangles come in grid order, so the points
//! spread over the whole surface; each is its triangle's centroid, the output's triangles being
//! under two voxels across). Every length is measured from the points' centroid `c` in units
//! of their RMS radius `r`, which removes translation and scale; only distances and
//! eigenvalues enter, which removes rotation and mirroring:
//!
//! | entries | what |
//! |---|---|
//! | 0–2 | eigenvalues of the points' second-moment tensor about `c` over `r²` (they sum to 1), largest first, times [`EIGEN_WEIGHT`] |
//! | 3 | sphericity `(36π V²)^⅓ / A` of the enclosed volume `V` and area `A` (exact, over every triangle; 1 for a ball, near 0 for a thin shell) |
//! | 4–17 | the shell distribution: share of the points within `tᵢ = 0.15·(i+1)·r` of `c` |
//! | 18–31 | the D2 distribution (Osada et al., "Shape distributions", ACM TOG 2002): share of pairs of [`D2_POINTS`] of the points (every 64th) within `sᵢ = 0.25·(i+1)·r` of each other |
//!
//! Both distributions are cumulative and smoothed: each distance counts linearly across one
//! step either side of a threshold, so a surface that moves by ε moves every entry by at most
//! ε / step, and no entry jumps when a distance crosses a threshold. The one pass over every
//! triangle (areas and volume) runs over fixed chunks combined in order, so the signature is
//! bit-identical whatever the thread count; the rest reads the points alone, which keeps the
//! cost a few per cent of the conversion (docs/PERFORMANCE.md, "Near-duplicate groups").

use crate::TriMesh;
use rayon::prelude::*;

/// Entries of a signature.
pub const SIGNATURE_LEN: usize = 32;
/// Thresholds of each distribution.
const STEPS: usize = 14;
/// Step of the shell distribution's thresholds, in units of `r`.
const SHELL_STEP: f64 = 0.15;
/// Step of the D2 distribution's thresholds, in units of `r`.
const D2_STEP: f64 = 0.25;
/// Area-stratified surface points the signature reads.
pub const SURFACE_POINTS: usize = 1 << 16;
/// Of those, the points whose pairwise distances make the D2 distribution (523 776 pairs:
/// with 2048 points the pairs were most of the signature's time, docs/PERFORMANCE.md).
pub const D2_POINTS: usize = 1024;
/// Weight of the eigenvalue entries: their differences between shapes are a third of the
/// distributions' per entry, and there are fewer of them.
pub const EIGEN_WEIGHT: f64 = 2.0;
/// Triangles per chunk of the parallel sums (fixed, so the sums do not depend on threads).
const CHUNK: usize = 1 << 14;

/// A shape's signature ([`shape_signature`]).
pub type ShapeSignature = [f32; SIGNATURE_LEN];

/// Euclidean distance between two signatures (of any equal length).
pub fn distance(a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// The corners of triangle `t` relative to `origin`, in double precision.
fn corners(mesh: &TriMesh, t: &[u32; 3], origin: [f64; 3]) -> [[f64; 3]; 3] {
    t.map(|i| {
        let p = mesh.positions[i as usize];
        [0, 1, 2].map(|a| f64::from(p[a]) - origin[a])
    })
}

fn triangle_area(v: &[[f64; 3]; 3]) -> f64 {
    let e1 = crate::vec3::sub(v[1], v[0]);
    let e2 = crate::vec3::sub(v[2], v[0]);
    0.5 * crate::vec3::norm(crate::vec3::cross(e1, e2))
}

/// Each triangle's area, and six times the enclosed volume (the signed volumes of the
/// tetrahedra from `origin`, divergence theorem), summed over fixed chunks in order.
fn areas_and_volume(mesh: &TriMesh, origin: [f64; 3]) -> (Vec<f64>, f64) {
    let parts: Vec<(Vec<f64>, f64)> = mesh
        .triangles
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut volume6 = 0.0;
            let areas = chunk
                .iter()
                .map(|t| {
                    let v = corners(mesh, t, origin);
                    volume6 += crate::vec3::dot(v[0], crate::vec3::cross(v[1], v[2]));
                    triangle_area(&v)
                })
                .collect();
            (areas, volume6)
        })
        .collect();
    let mut areas = Vec::with_capacity(mesh.triangles.len());
    let mut volume6 = 0.0;
    for (a, v) in parts {
        areas.extend(a);
        volume6 += v;
    }
    (areas, volume6)
}

/// [`SURFACE_POINTS`] points, one per equal share of the total `area` along the triangle
/// order, each its triangle's centroid.
fn stratified_points(mesh: &TriMesh, areas: &[f64], area: f64) -> Vec<[f64; 3]> {
    let mut points = Vec::with_capacity(SURFACE_POINTS);
    let step = area / SURFACE_POINTS as f64;
    let mut next = 0.5 * step;
    let mut walked = 0.0;
    for (t, a) in mesh.triangles.iter().zip(areas) {
        walked += a;
        while walked > next && points.len() < SURFACE_POINTS {
            let v = corners(mesh, t, [0.0; 3]);
            points.push([0, 1, 2].map(|k| (v[0][k] + v[1][k] + v[2][k]) / 3.0));
            next += step;
        }
    }
    points
}

/// The points' centroid and second-moment tensor about it.
fn centroid_and_covariance(points: &[[f64; 3]]) -> ([f64; 3], [[f64; 3]; 3]) {
    let n = points.len().max(1) as f64;
    let mut c = [0.0; 3];
    for p in points {
        for k in 0..3 {
            c[k] += p[k] / n;
        }
    }
    let mut cov = [[0.0; 3]; 3];
    for p in points {
        let d = crate::vec3::sub(*p, c);
        for a in 0..3 {
            for b in 0..3 {
                cov[a][b] += d[a] * d[b] / n;
            }
        }
    }
    (c, cov)
}

/// Eigenvalues of a symmetric 3×3 matrix, largest first (the trigonometric closed form:
/// O. K. Smith, "Eigenvalues of a symmetric 3 × 3 matrix", CACM 4(4), 1961).
fn symmetric_eigenvalues(m: &[[f64; 3]; 3]) -> [f64; 3] {
    let p1 = m[0][1].powi(2) + m[0][2].powi(2) + m[1][2].powi(2);
    let q = (m[0][0] + m[1][1] + m[2][2]) / 3.0;
    let p2 = (0..3).map(|i| (m[i][i] - q).powi(2)).sum::<f64>() + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    if p <= f64::EPSILON * q.abs().max(f64::MIN_POSITIVE) {
        return [q; 3];
    }
    let b: Vec<[f64; 3]> = (0..3)
        .map(|i| [0, 1, 2].map(|j| (m[i][j] - if i == j { q } else { 0.0 }) / p))
        .collect();
    let det = b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1])
        - b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0])
        + b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0]);
    let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
    let big = q + 2.0 * p * phi.cos();
    let small = q + 2.0 * p * (phi + 2.0 * std::f64::consts::PI / 3.0).cos();
    [big, 3.0 * q - big - small, small]
}

/// Weights and weighted distances per whole step of distance (bin `b` holds `b ≤ x < b+1`;
/// the last bin everything beyond the last threshold's reach), from which the smoothed
/// cumulative distribution follows exactly ([`Binned::smoothed`]).
#[derive(Debug, Clone, Copy)]
struct Binned {
    weight: [f64; STEPS + 2],
    moment: [f64; STEPS + 2],
}

impl Binned {
    fn new() -> Self {
        Self {
            weight: [0.0; STEPS + 2],
            moment: [0.0; STEPS + 2],
        }
    }

    /// Adds weight `w` at distance `x` (in steps).
    fn add(&mut self, x: f64, w: f64) {
        let b = (x.max(0.0) as usize).min(STEPS + 1);
        self.weight[b] += w;
        self.moment[b] += w * x;
    }

    fn merge(mut self, o: Binned) -> Binned {
        for b in 0..STEPS + 2 {
            self.weight[b] += o.weight[b];
            self.moment[b] += o.moment[b];
        }
        self
    }

    /// The smoothed cumulative distribution over `total` weight: entry `i` (threshold `i + 1`
    /// steps) counts a distance `x` wholly when `x ≤ i`, not at all when `x ≥ i + 2`, and
    /// `(i + 2 − x) / 2` between. With `R(k) = Σ_{x<k} (k − x) = k·W(k) − M(k)` (`W`, `M` the
    /// weight and moment of the bins below the whole number `k`), entry `i` is
    /// `(R(i + 2) − R(i)) / 2`.
    fn smoothed(&self, total: f64) -> [f64; STEPS] {
        let mut ramp = [0.0; STEPS + 2];
        let (mut w, mut m) = (0.0, 0.0);
        for k in 1..STEPS + 2 {
            w += self.weight[k - 1];
            m += self.moment[k - 1];
            ramp[k] = k as f64 * w - m;
        }
        std::array::from_fn(|i| (ramp[i + 2] - ramp[i]) / (2.0 * total.max(f64::MIN_POSITIVE)))
    }
}

/// The shell distribution: the share of the points near each threshold distance from `c`.
fn shell_distribution(points: &[[f64; 3]], c: [f64; 3], r: f64) -> [f64; STEPS] {
    let mut bins = Binned::new();
    for p in points {
        bins.add(crate::vec3::dist2(*p, c).sqrt() / r / SHELL_STEP, 1.0);
    }
    bins.smoothed(points.len() as f64)
}

/// The D2 distribution of the stratified points: the share of pairs near each threshold.
fn d2_distribution(points: &[[f64; 3]], r: f64) -> [f64; STEPS] {
    let scale = 1.0 / (r * D2_STEP);
    let parts: Vec<Binned> = (0..points.len())
        .into_par_iter()
        .map(|i| {
            let mut bins = Binned::new();
            for q in &points[i + 1..] {
                bins.add(crate::vec3::dist2(points[i], *q).sqrt() * scale, 1.0);
            }
            bins
        })
        .collect();
    let pairs = (points.len() * points.len().saturating_sub(1) / 2) as f64;
    parts
        .into_iter()
        .fold(Binned::new(), Binned::merge)
        .smoothed(pairs)
}

/// The signature of a mesh (the watertight output, in any frame); `None` when it has no area.
pub fn shape_signature(mesh: &TriMesh) -> Option<ShapeSignature> {
    let origin = mesh
        .bounds()
        .map(|(lo, hi)| [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a])))?;
    let (areas, volume6) = areas_and_volume(mesh, origin);
    let area: f64 = areas.iter().sum();
    if area.is_nan() || area <= 0.0 {
        return None;
    }
    let points = stratified_points(mesh, &areas, area);
    let (c, cov) = centroid_and_covariance(&points);
    let r2 = cov[0][0] + cov[1][1] + cov[2][2];
    if r2.is_nan() || r2 <= 0.0 {
        return None;
    }
    let r = r2.sqrt();
    let eigen = symmetric_eigenvalues(&cov).map(|l| EIGEN_WEIGHT * (l / r2).max(0.0));
    let volume = volume6.abs() / 6.0;
    let sphericity = (36.0 * std::f64::consts::PI * volume * volume).cbrt() / area;
    let shell = shell_distribution(&points, c, r);
    let stride = (points.len() / D2_POINTS).max(1);
    let d2_points: Vec<[f64; 3]> = points.iter().step_by(stride).copied().collect();
    let d2 = d2_distribution(&d2_points, r);
    let mut s = [0.0f32; SIGNATURE_LEN];
    let values = eigen.iter().chain([&sphericity]).chain(&shell).chain(&d2);
    for (slot, v) in s.iter_mut().zip(values) {
        *slot = *v as f32;
    }
    Some(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigenvalues_of_a_diagonal_and_a_rotated_matrix() {
        let d = [[3.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.0]];
        let e = symmetric_eigenvalues(&d);
        for (got, want) in e.iter().zip([3.0, 2.0, 1.0]) {
            assert!((got - want).abs() < 1e-12, "{e:?}");
        }
        // [[2, 1], [1, 2]] has eigenvalues 3 and 1; the third axis holds 5.
        let m = [[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 5.0]];
        let e = symmetric_eigenvalues(&m);
        for (got, want) in e.iter().zip([5.0, 3.0, 1.0]) {
            assert!((got - want).abs() < 1e-12, "{e:?}");
        }
        assert_eq!(
            symmetric_eigenvalues(&[[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]]),
            [2.0; 3]
        );
    }

    #[test]
    fn smoothed_steps_ramp_across_each_threshold() {
        let at = |x: f64| {
            let mut bins = Binned::new();
            bins.add(x, 2.0);
            bins.smoothed(2.0)
        };
        assert_eq!(at(0.0), [1.0; STEPS]);
        assert_eq!(at(0.5)[..2], [0.75, 1.0]);
        assert_eq!(at(1.0)[0], 0.5);
        assert_eq!(at(1.5)[0], 0.25);
        assert_eq!(at(2.0)[0], 0.0);
        assert_eq!(at(3.25)[..4], [0.0, 0.0, 0.375, 0.875]);
        assert_eq!(at(99.0), [0.0; STEPS]);
        for x in [0.3, 1.7, 5.2, 14.9] {
            let (a, b) = (at(x), at(x + 1e-6));
            assert!(a.iter().zip(&b).all(|(p, q)| (p - q).abs() < 1e-5), "{x}");
        }
    }

    #[test]
    fn an_empty_mesh_has_no_signature() {
        assert!(shape_signature(&TriMesh::default()).is_none());
    }
}
