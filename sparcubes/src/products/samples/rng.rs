//! Counter-based random numbers: every number is a hash of `(seed, stream, index, k)`, so a
//! sample's numbers do not depend on which thread draws it or in which order.

/// SplitMix64 finaliser: a bijective 64-bit mix (Steele, Lea & Flood, "Fast splittable
/// pseudorandom number generators", 2014).
#[inline]
pub fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The random numbers of one sample: `Draw::new(seed, stream, index).uniform(k)` is the
/// `k`-th number of sample `index` of `stream`.
#[derive(Debug, Clone, Copy)]
pub struct Draw {
    base: u64,
}

impl Draw {
    /// The numbers of sample `index` of `stream` under `seed`.
    #[inline]
    pub fn new(seed: u64, stream: u64, index: u64) -> Self {
        Self {
            base: mix(seed ^ mix(stream.wrapping_mul(0xD1B5_4A32_D192_ED03) ^ mix(index))),
        }
    }

    /// Number `k`, uniform in `[0, 1)` with 53 random bits.
    #[inline]
    pub fn uniform(&self, k: u64) -> f64 {
        (mix(self.base ^ mix(k.wrapping_add(1))) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Number `k` of a standard normal distribution (Box–Muller on uniforms `2k`, `2k + 1`).
    #[inline]
    pub fn normal(&self, k: u64) -> f64 {
        let u1 = 1.0 - self.uniform(2 * k); // (0, 1]
        let u2 = self.uniform(2 * k + 1);
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// `N` independent normal numbers with standard deviation `sigma`, each redrawn while it
    /// lies outside `[-bound, bound]`, from numbers `k, k + 1, …` (a pair of numbers per try).
    ///
    /// Marsaglia's polar method (Marsaglia & Bray, "A convenient method for generating normal
    /// variables", SIAM Review 1964): a point uniform in the unit disk, `(v₁, v₂)` with
    /// `s = v₁² + v₂²`, gives the two independent standard normals `vᵢ·√(−2 ln s / s)`; points
    /// outside the disk (21 %) are redrawn. Every accepted normal is used, so three offsets
    /// cost about two logarithms and no trigonometric function (Box–Muller's cosine was most
    /// of the near draws' time). After `64·N` tries the missing numbers are the last one
    /// clamped to the bound.
    #[inline]
    pub fn truncated_normals<const N: usize>(&self, k: u64, sigma: f64, bound: f64) -> [f64; N] {
        let mut out = [0.0; N];
        let mut filled = 0;
        let mut last = 0.0;
        for j in 0..64 * N as u64 {
            let v1 = 2.0 * self.uniform(k + 2 * j) - 1.0;
            let v2 = 2.0 * self.uniform(k + 2 * j + 1) - 1.0;
            let s = v1 * v1 + v2 * v2;
            if s >= 1.0 || s == 0.0 {
                continue;
            }
            let f = sigma * (-2.0 * s.ln() / s).sqrt();
            for x in [v1 * f, v2 * f] {
                last = x;
                if x.abs() <= bound {
                    out[filled] = x;
                    filled += 1;
                    if filled == N {
                        return out;
                    }
                }
            }
        }
        for x in &mut out[filled..] {
            *x = last.clamp(-bound, bound);
        }
        out
    }
}

/// Three uniform numbers in `[0, 1)` for sample `index` of `stream` under `seed`.
#[inline]
pub fn uniforms(seed: u64, stream: u64, index: u64) -> [f64; 3] {
    let d = Draw::new(seed, stream, index);
    [d.uniform(0), d.uniform(1), d.uniform(2)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_and_normal_moments() {
        let n = 200_000u64;
        let (mut s, mut s2, mut ns, mut ns2) = (0.0, 0.0, 0.0, 0.0);
        for i in 0..n {
            let d = Draw::new(42, 3, i);
            let u = d.uniform(0);
            assert!((0.0..1.0).contains(&u));
            s += u;
            s2 += u * u;
            let g = d.normal(1);
            ns += g;
            ns2 += g * g;
        }
        let nf = n as f64;
        assert!((s / nf - 0.5).abs() < 0.005);
        assert!((s2 / nf - 1.0 / 3.0).abs() < 0.005);
        assert!((ns / nf).abs() < 0.01);
        assert!((ns2 / nf - 1.0).abs() < 0.02);
        // Different streams and seeds give different numbers.
        assert_ne!(uniforms(1, 1, 0), uniforms(1, 2, 0));
        assert_ne!(uniforms(1, 1, 0), uniforms(2, 1, 0));
        let t: [f64; 3] = Draw::new(1, 1, 1).truncated_normals(0, 1.0, 0.1);
        assert!(t.iter().all(|t| t.abs() <= 0.1));
    }

    #[test]
    fn truncated_normals_have_the_moments_of_a_truncated_normal() {
        // σ = 0.5 truncated at ±1 (2σ): variance σ²·(1 − 2·2·φ(2)/(2Φ(2) − 1)) = 0.25 · 0.7737
        // (φ(2) = 0.053991, Φ(2) = 0.977250), fourth moment checked through the variance only.
        let n = 200_000u64;
        let (mut s, mut s2, mut cross, mut outside) = ([0.0; 3], [0.0; 3], 0.0, 0);
        for i in 0..n {
            let x: [f64; 3] = Draw::new(7, 3, i).truncated_normals(8, 0.5, 1.0);
            for a in 0..3 {
                s[a] += x[a];
                s2[a] += x[a] * x[a];
                outside += usize::from(x[a].abs() > 1.0);
            }
            cross += x[0] * x[1] + x[1] * x[2];
        }
        let nf = n as f64;
        let phi2 = 0.053_990_966_513_188;
        let big_phi2 = 0.977_249_868_051_821;
        let variance = 0.25 * (1.0 - 4.0 * phi2 / (2.0 * big_phi2 - 1.0));
        assert_eq!(outside, 0);
        for a in 0..3 {
            assert!((s[a] / nf).abs() < 0.005, "mean {a}: {}", s[a] / nf);
            assert!(
                (s2[a] / nf - variance).abs() < 0.005,
                "variance {a}: {} vs {variance}",
                s2[a] / nf
            );
        }
        // The axes are independent (the two normals of one pair are uncorrelated).
        assert!((cross / (2.0 * nf)).abs() < 0.003, "{}", cross / (2.0 * nf));
        // A bound far below σ still gives numbers within it.
        let tiny: [f64; 3] = Draw::new(1, 1, 1).truncated_normals(0, 1.0, 1e-9);
        assert!(tiny.iter().all(|t| t.abs() <= 1e-9));
    }
}
