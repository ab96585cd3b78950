//! A shape signature of the watertight output: a fixed-length vector that two copies of one
//! shape share whatever rigid motion, uniform scale, mirroring or triangulation separates
//! them, so that near-duplicates are close in plain Euclidean distance ([`distance`]).
//!
//! It is read from the surface of the extracted mesh (never the source's triangle list, so a
//! re-triangulated source gives the same output up to the grid's rounding), through a sample
//! of up to 16384 of its triangles ([`sample_size`]) taken in one pass over them
//! ([`surface_pass`]) that also sums the area and the volume: one triangle drawn by a hash
//! from each of equal stretches of the triangle order (stratified sampling: the output's
//! triangles come in grid order, so the sample spreads over the whole surface; the middle of
//! each stretch, taken at first, aliased with the extraction's period along the grid), each
//! standing for the surface by its centroid with its area as weight (the output's triangles
//! are under two voxels across). Every length is measured from the sample's weighted centroid
//! `c` in units of its RMS radius `r`, which removes translation and scale; only distances and
//! eigenvalues enter, which removes rotation and mirroring:
//!
//! | entries | what |
//! |---|---|
//! | 0–2 | eigenvalues of the sample's second-moment tensor about `c` over `r²` (they sum to 1), largest first, times [`EIGEN_WEIGHT`] |
//! | 3 | sphericity `(36π V²)^⅓ / A` of the enclosed volume `V` and the area `A` (both exact, over every triangle; 1 for a ball, near 0 for a thin shell) |
//! | 4–17 | the shell distribution: share of the sampled area within `tᵢ = 0.15·(i+1)·r` of `c` |
//! | 18–31 | the D2 distribution (Osada et al., "Shape distributions", ACM TOG 2002): share of pairs of surface points within `sᵢ = 0.25·(i+1)·r` of each other, over [`D2_ROUNDS`] rounds that pair each sampled triangle with another drawn by a hash |
//!
//! Both distributions are cumulative and smoothed: each distance counts linearly across one
//! step either side of a threshold, so a surface that moves by ε moves every entry by at most
//! ε / step, and no entry jumps when a distance crosses a threshold. The pass also measures the
//! volume, which the quality facts need anyway; the sample's statistics are then a fixed
//! amount of work whatever the mesh's size, so the signature costs a few milliseconds (docs/PERFORMANCE.md,
//! "Near-duplicate groups"). Every sum runs over fixed parts combined in a fixed order, so the
//! signature is bit-identical whatever the thread count.

use crate::vec3::{cross, dist2, dot, norm, sub};
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
/// Most triangles the signature samples ([`sample_size`]).
pub const SAMPLED_TRIANGLES: usize = 1 << 14;

/// How many of `t` triangles the signature samples: all, up to [`SAMPLED_TRIANGLES`]. (A
/// sample that shrank with the output, one triangle in eight down to 4096, was a third
/// cheaper on the smallest outputs but left copies in the tests up to 0.017 apart, over half
/// the default threshold; the full sample keeps them under 0.008.)
pub fn sample_size(t: usize) -> usize {
    t.min(SAMPLED_TRIANGLES)
}

/// Rounds of pairs for the D2 distribution: each round pairs every sample with one other
/// (`partner`), 131 072 pairs for a full sample (a quarter of the 523 776 of all pairs among
/// 1024 points, with every sample in them). Four rounds left the copies of the tests up to
/// 0.014 apart, against under 0.009 with eight.
pub const D2_ROUNDS: usize = 8;
/// A sample's partner in round `round` of the D2 pairings: a SplitMix64 hash of the two
/// (Steele, Lea and Flood, "Fast splittable pseudorandom number generators", OOPSLA 2014),
/// so that the partners of neighbours along the triangle order lie anywhere on the surface,
/// in no pattern a turned or mirrored copy's order could change.
fn partner(i: usize, round: usize, n: usize) -> usize {
    let z = mix((round as u64) << 32 | i as u64);
    // The high half of the hash times n: in 0..n without a division (Lemire, "Fast random
    // integer generation in an interval", ACM TOMACS 2019).
    (((z >> 32) * n as u64) >> 32) as usize
}

/// The SplitMix64 finaliser of `x` ([`partner`]).
fn mix(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Weight of the eigenvalue entries: their differences between shapes are a third of the
/// distributions' per entry, and there are fewer of them.
pub const EIGEN_WEIGHT: f64 = 2.0;

/// Triangles per part of the pass over the mesh ([`surface_pass`]; fixed, so its sums do not
/// depend on the threads).
const PART_TRIANGLES: usize = 1 << 14;

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

/// A sampled triangle: its centroid and its area (the weight it stands for), in single
/// precision (the output's positions are), 16 bytes: the D2 pairs' random reads then stay in
/// a quarter of a megabyte (a core's L2 cache), and no copy is made for them.
#[derive(Debug, Clone, Copy)]
struct Sample {
    point: [f32; 3],
    weight: f32,
}

impl Sample {
    /// The centroid in double precision.
    fn at(&self) -> [f64; 3] {
        self.point.map(f64::from)
    }

    /// The area in double precision.
    fn area(&self) -> f64 {
        f64::from(self.weight)
    }
}

/// What one pass over a mesh's triangles measures ([`surface_pass`]): its signed volume (the
/// quality facts' output volume), its area and, when asked, the signature's sample.
#[derive(Debug, Clone, Default)]
pub struct SurfacePass {
    /// Signed volume: [`TriMesh::signed_volume`]'s terms, summed over fixed parts in order.
    pub volume: f64,
    /// Total area.
    pub area: f64,
    samples: Vec<Sample>,
}

impl SurfacePass {
    /// Adds a later part's sums and samples.
    fn append(mut self, later: SurfacePass) -> SurfacePass {
        self.volume += later.volume;
        self.area += later.area;
        self.samples.extend(later.samples);
        self
    }
}

/// The first triangle of the j-th of `n` equal stretches of `t` triangles' order (`n ≤ t`, so
/// no stretch is empty).
fn stretch_start(j: usize, t: usize, n: usize) -> usize {
    (j * t) / n
}

/// The triangle that sample `j` of `n` stands for among `t` (`n ≤ t`): one drawn by a hash of
/// `j` ([`mix`]) within the j-th of n equal stretches of the triangle order (stratified
/// sampling). The middle of each stretch, as taken at first, aliased with the period of the
/// extraction's triangles along the grid: a box's turned copy came out 0.08 from the box.
fn sampled_triangle(j: usize, t: usize, n: usize) -> usize {
    let (lo, hi) = (stretch_start(j, t, n), stretch_start(j + 1, t, n));
    lo + (((mix(j as u64 | 1 << 63) >> 32) * (hi - lo) as u64) >> 32) as usize
}

/// The first sample of `n` among `t` triangles whose triangle is at or after `start`.
fn first_sample_from(start: usize, t: usize, n: usize) -> usize {
    if n == 0 || start >= t {
        return n;
    }
    // The stretch that holds `start`: the last `j` whose stretch starts at or before it.
    let mut j = (start * n) / t;
    while stretch_start(j + 1, t, n) <= start {
        j += 1;
    }
    while stretch_start(j, t, n) > start {
        j -= 1;
    }
    if sampled_triangle(j, t, n) < start {
        j + 1
    } else {
        j
    }
}

/// One pass over the mesh, in parallel over fixed parts of 16384 triangles combined in
/// order: the volume and area, and with `sample` the [`sample_size`] sampled triangles, each
/// its centroid weighted by its area. Reading the sample in the same pass
/// that streams the triangles for the volume saves the sample's scattered reads and a second
/// pass for the area (on a mesh that is no longer in the cache, they were most of the
/// signature's time).
pub fn surface_pass(mesh: &TriMesh, sample: bool) -> SurfacePass {
    let t = mesh.triangles.len();
    let n = if sample { sample_size(t) } else { 0 };
    let parts: Vec<SurfacePass> = (0..t.div_ceil(PART_TRIANGLES))
        .into_par_iter()
        .map(|p| {
            let range = p * PART_TRIANGLES..((p + 1) * PART_TRIANGLES).min(t);
            part_pass(mesh, range, n)
        })
        .collect();
    let mut out = SurfacePass {
        samples: Vec::with_capacity(n),
        ..SurfacePass::default()
    };
    for part in parts {
        out = out.append(part);
    }
    out
}

/// [`surface_pass`] over the triangles `range`, with the samples of `n` that fall in it.
fn part_pass(mesh: &TriMesh, range: std::ops::Range<usize>, n: usize) -> SurfacePass {
    let t = mesh.triangles.len();
    let mut next = first_sample_from(range.start, t, n);
    // The triangle of sample `next` (none past the last), found once per sample.
    let mut next_triangle = if next < n {
        sampled_triangle(next, t, n)
    } else {
        usize::MAX
    };
    // Locals rather than fields of the result, so that the sums stay in registers past the
    // sample's pushes.
    let (mut six_volume, mut area_sum) = (0.0, 0.0);
    let mut samples = Vec::with_capacity((range.len() * n).div_ceil(t.max(1)) + 1);
    for i in range {
        let [a, b, c] = mesh.triangle(i);
        // Six times `TriMesh::signed_volume`'s term (the same triple product).
        six_volume += dot(a, cross(b, c));
        let area = 0.5 * norm(cross(sub(b, a), sub(c, a)));
        area_sum += area;
        if i == next_triangle {
            samples.push(Sample {
                point: [0, 1, 2].map(|k| ((a[k] + b[k] + c[k]) * (1.0 / 3.0)) as f32),
                weight: area as f32,
            });
            next += 1;
            next_triangle = if next < n {
                sampled_triangle(next, t, n)
            } else {
                usize::MAX
            };
        }
    }
    SurfacePass {
        volume: six_volume / 6.0,
        area: area_sum,
        samples,
    }
}

/// The samples' weighted centroid, second-moment tensor about it, and total weight.
fn centroid_and_covariance(samples: &[Sample]) -> ([f64; 3], [[f64; 3]; 3], f64) {
    let total: f64 = samples.iter().map(Sample::area).sum();
    let w = 1.0 / total.max(f64::MIN_POSITIVE);
    let mut c = [0.0; 3];
    for s in samples {
        let p = s.at();
        for k in 0..3 {
            c[k] += p[k] * s.area() * w;
        }
    }
    let mut cov = [[0.0; 3]; 3];
    for s in samples {
        let d = sub(s.at(), c);
        for a in 0..3 {
            for b in 0..3 {
                cov[a][b] += d[a] * d[b] * s.area() * w;
            }
        }
    }
    (c, cov, total)
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

/// The shell distribution: the share of the sampled area near each threshold distance from
/// `c`.
fn shell_distribution(samples: &[Sample], c: [f64; 3], r: f64, total: f64) -> [f64; STEPS] {
    let scale = 1.0 / (r * SHELL_STEP);
    let mut bins = Binned::new();
    for s in samples {
        bins.add(dist2(s.at(), c).sqrt() * scale, s.area());
    }
    bins.smoothed(total)
}

/// The D2 distribution over [`D2_ROUNDS`] rounds of pairs of the samples ([`partner`]), each pair
/// weighted by both its samples' areas: the share of the pairs' weight near each threshold.
fn d2_distribution(samples: &[Sample], r: f64) -> [f64; STEPS] {
    const BLOCK: usize = 64;
    let n = samples.len();
    let scale = 1.0 / (r * D2_STEP);
    let rounds: Vec<(Binned, f64)> = (0..D2_ROUNDS)
        .into_par_iter()
        .map(|round| {
            let mut bins = Binned::new();
            let mut total = 0.0;
            // In blocks: the distances of a block first (their square roots then run side by
            // side rather than each waiting for the one before to be binned), then its bins.
            let (mut distance, mut weight) = ([0.0f32; BLOCK], [0.0f32; BLOCK]);
            for (b, block) in samples.chunks(BLOCK).enumerate() {
                for (k, p) in block.iter().enumerate() {
                    let q = &samples[partner(b * BLOCK + k, round, n)];
                    let (p3, q3) = (p.point, q.point);
                    let d2: f32 = (0..3).map(|a| (p3[a] - q3[a]) * (p3[a] - q3[a])).sum();
                    distance[k] = d2;
                    weight[k] = p.weight * q.weight;
                }
                for d in &mut distance[..block.len()] {
                    *d = d.sqrt();
                }
                for k in 0..block.len() {
                    let w = f64::from(weight[k]);
                    bins.add(f64::from(distance[k]) * scale, w);
                    total += w;
                }
            }
            (bins, total)
        })
        .collect();
    // Merged in round order, so the sums do not depend on the threads.
    let (mut bins, mut total) = (Binned::new(), 0.0);
    for (b, t) in rounds {
        bins = bins.merge(b);
        total += t;
    }
    bins.smoothed(total)
}

/// The signature of a mesh (the watertight output, in any frame); `None` when it has no area.
pub fn shape_signature(mesh: &TriMesh) -> Option<ShapeSignature> {
    signature_of(&surface_pass(mesh, true))
}

/// The signature from a [`surface_pass`] that took the sample (`None` when it has no area or
/// took no sample).
pub fn signature_of(pass: &SurfacePass) -> Option<ShapeSignature> {
    let samples = &pass.samples;
    let (c, cov, total) = centroid_and_covariance(samples);
    let r2 = cov[0][0] + cov[1][1] + cov[2][2];
    if samples.is_empty() || r2.is_nan() || r2 <= 0.0 || total <= 0.0 {
        return None;
    }
    let r = r2.sqrt();
    let eigen = symmetric_eigenvalues(&cov).map(|l| EIGEN_WEIGHT * (l / r2).max(0.0));
    let volume = pass.volume;
    let sphericity = (36.0 * std::f64::consts::PI * volume * volume).cbrt() / pass.area;
    let shell = shell_distribution(samples, c, r, total);
    let d2 = d2_distribution(samples, r);
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
    fn the_first_sample_of_a_part_is_the_first_at_or_after_its_start() {
        for (t, n) in [
            (1, 1),
            (7, 7),
            (10, 3),
            (100, 7),
            (100_003, 16_384),
            (40_000, 16_384),
        ] {
            for start in (0..=t).step_by((t / 97).max(1)) {
                let want = (0..n)
                    .find(|&j| sampled_triangle(j, t, n) >= start)
                    .unwrap_or(n);
                assert_eq!(
                    first_sample_from(start, t, n).min(n),
                    want,
                    "t {t} n {n} {start}"
                );
            }
        }
    }

    #[test]
    fn the_pass_measures_what_the_mesh_does() {
        let mesh = crate::shapes::torus([0.0; 3], 1.0, 0.35, 300);
        let t = mesh.triangles.len();
        assert!(t > 2 * PART_TRIANGLES, "{t} triangles: more than one part");
        let pass = surface_pass(&mesh, true);
        assert!((pass.volume - mesh.signed_volume()).abs() < 1e-9 * mesh.signed_volume());
        assert!((pass.area - mesh.area()).abs() < 1e-9 * mesh.area());
        let n = sample_size(t);
        assert_eq!(pass.samples.len(), n);
        for (j, s) in pass.samples.iter().enumerate().step_by(331) {
            let [a, b, c] = mesh.triangle(sampled_triangle(j, t, n));
            assert_eq!(
                s.point,
                [0, 1, 2].map(|k| ((a[k] + b[k] + c[k]) * (1.0 / 3.0)) as f32),
                "{j}"
            );
        }
        // A torus about the origin in the xy plane: the sample's centroid is near the origin,
        // its second moments near diagonal with x and y alike.
        let (c, cov, _) = centroid_and_covariance(&pass.samples);
        assert!(c.iter().all(|x| x.abs() < 1e-3), "{c:?}");
        assert!(
            (cov[0][0] - cov[1][1]).abs() < 1e-3 && cov[0][1].abs() < 1e-3,
            "{cov:?}"
        );
        assert!(cov[2][2] < 0.2 * cov[0][0], "{cov:?}");
        let bare = surface_pass(&mesh, false);
        assert!(bare.samples.is_empty() && signature_of(&bare).is_none());
        assert_eq!(bare.volume.to_bits(), pass.volume.to_bits());
    }

    #[test]
    fn an_empty_mesh_has_no_signature() {
        assert!(shape_signature(&TriMesh::default()).is_none());
    }
}
