//! `sparc3d bench-dedup [--items N] [--threshold T]`: `dedup`'s grouping timed on N synthetic
//! shape signatures (docs/PERFORMANCE.md, "Near-duplicate groups"). Each synthetic shape is
//! a signature built as `sparcubes::products::shape_signature` lays one out (eigenvalue
//! shares, a sphericity, two smoothed cumulative distributions of distances drawn from a
//! two-mode mixture); a third of them get one to three copies moved by a small noise, as
//! re-exported copies of an asset are. Fixed seed: the same signatures on every run.

use crate::rows::near_duplicates::groups;
use anyhow::Result;
use sparcubes::products::shape_signature::SIGNATURE_LEN;
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `sparc3d bench-dedup`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Synthetic signatures to group.
    #[arg(long, default_value_t = 1_000_000)]
    pub items: usize,
    #[command(flatten)]
    pub threshold: crate::commands::dedup::Threshold,
}

/// A fixed-seed generator of uniform numbers in `[0, 1)` (Knuth's MMIX LCG).
struct Uniform(u64);

impl Uniform {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A normal deviate (Box–Muller).
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.next().max(1e-300), self.next());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// The smoothed cumulative distribution, at 14 thresholds `step·(i+1)`, of a mixture of two
/// normals with random means and spreads (lengths in units of the RMS radius).
fn distribution(u: &mut Uniform, step: f64, reach: f64) -> [f64; 14] {
    let modes: Vec<(f64, f64, f64)> = (0..2)
        .map(|_| {
            (
                0.2 + u.next() * reach,
                0.03 + u.next() * 0.4,
                0.2 + u.next(),
            )
        })
        .collect();
    let total: f64 = modes.iter().map(|m| m.2).sum();
    std::array::from_fn(|i| {
        let t = step * (i + 1) as f64;
        let cdf = |(mean, sd, w): &(f64, f64, f64)| {
            w * 0.5 * (1.0 + erf((t - mean) / (sd * 2f64.sqrt())))
        };
        modes.iter().map(cdf).sum::<f64>() / total
    })
}

/// The error function (Abramowitz and Stegun 7.1.26, absolute error under 1.5e-7).
fn erf(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.3275911 * x.abs());
    let poly = t
        * (0.254829592
            + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429))));
    (1.0 - poly * (-x * x).exp()).copysign(x)
}

/// One synthetic shape's signature.
fn shape(u: &mut Uniform) -> Vec<f32> {
    let mut eigen = [u.next() + 0.05, u.next() + 0.05, u.next() + 0.05];
    eigen.sort_by(|a, b| b.total_cmp(a));
    let sum: f64 = eigen.iter().sum();
    let mut s: Vec<f64> = eigen.iter().map(|e| 2.0 * e / sum).collect();
    s.push(u.next());
    s.extend(distribution(u, 0.15, 1.6));
    s.extend(distribution(u, 0.25, 2.5));
    s.into_iter().map(|x| x as f32).collect()
}

/// `n` signatures: shapes, a third of them followed by one to three noisy copies.
pub fn synthetic(n: usize) -> Vec<Vec<f32>> {
    let mut u = Uniform(2026);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let base = shape(&mut u);
        let copies = if u.next() < 1.0 / 3.0 {
            1 + (u.next() * 3.0) as usize
        } else {
            0
        };
        out.push(base.clone());
        for _ in 0..copies.min(n - out.len()) {
            let noise = |x: &f32| (f64::from(*x) + 0.003 * u.normal()) as f32;
            out.push(base.iter().map(noise).collect());
        }
    }
    debug_assert!(out.iter().all(|s| s.len() == SIGNATURE_LEN));
    out
}

/// Runs `sparc3d bench-dedup`.
pub fn run(args: Args) -> Result<ExitCode> {
    let t = Instant::now();
    let signatures = synthetic(args.items);
    let made = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let found = groups(&signatures, args.threshold.value);
    let grouped = t.elapsed().as_secs_f64();
    let members: usize = found.iter().map(|g| g.members.len()).sum();
    println!(
        "{} signatures ({made:.1} s to make): {} groups, {members} items dropped, grouped in \
         {grouped:.2} s (threshold {}); peak RSS {} MiB",
        signatures.len(),
        found.len(),
        args.threshold.value,
        crate::util::memory::peak_rss_bytes().unwrap_or(0) >> 20
    );
    Ok(ExitCode::SUCCESS)
}
