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

    /// A normal number with standard deviation `sigma`, redrawn (from later numbers) while it
    /// lies outside `[-bound, bound]`; after 64 draws it is clamped. `k` is the first of the
    /// numbers used, and numbers `k..k + 64` are reserved for it.
    #[inline]
    pub fn truncated_normal(&self, k: u64, sigma: f64, bound: f64) -> f64 {
        let mut x = 0.0;
        for j in 0..64 {
            x = sigma * self.normal(k + j);
            if x.abs() <= bound {
                return x;
            }
        }
        x.clamp(-bound, bound)
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
        let t = Draw::new(1, 1, 1).truncated_normal(0, 1.0, 0.1);
        assert!(t.abs() <= 0.1);
    }
}
