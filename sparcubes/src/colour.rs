//! sRGB and linear light, and bytes of [0, 1] values: the colour arithmetic that reading
//! materials, sampling attributes and writing coloured meshes share.

/// sRGB value in [0, 1] to linear (IEC 61966-2-1).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear value in [0, 1] → sRGB in [0, 1] (IEC 61966-2-1).
pub fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Rounds a value in [0, 1] to a byte.
pub fn to_byte(x: f32) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// `to_byte(linear_to_srgb(x))` by table: the least linear value of each byte from 1 to 255,
/// found once by bisection over the floats, and the byte at the start of each run of floats
/// that share their top 16 bits (sign, exponent and 7 bits of mantissa: below 1 % of the
/// value wide, narrower than an sRGB step anywhere in [0, 1]). A lookup reads its run's first
/// byte and steps past at most a threshold or two, instead of a power or a search of the
/// 255 thresholds (the attribute stage encodes three a cell). Equal to the direct formula for
/// every float in [0, 1], which a test checks on a dense sweep and on both sides of every
/// threshold.
pub struct SrgbBytes {
    /// `least[b - 1]`: the least x in [0, 1] whose byte is at least `b`; `least[255]` is
    /// infinite, so that no float steps past 255.
    least: [f32; 256],
    /// `first[i]`: the byte of the float whose bits are `i << 16`, for every such float in
    /// [0, 1].
    first: Vec<u8>,
}

impl SrgbBytes {
    /// Builds the tables.
    pub fn new() -> Self {
        let byte = |x: f32| to_byte(linear_to_srgb(x));
        let least: [f32; 256] = std::array::from_fn(|i| {
            let Ok(b) = u8::try_from(i + 1) else {
                return f32::INFINITY;
            };
            // Non-negative floats order as their bits do: bisect on the bits in [0, 1].
            let (mut lo, mut hi) = (0u32, 1.0f32.to_bits());
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if byte(f32::from_bits(mid)) >= b {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            f32::from_bits(lo)
        });
        let first = (0..=RUN_OF_ONE)
            .map(|i| {
                let x = f32::from_bits(i << 16);
                least.partition_point(|&t| t <= x) as u8
            })
            .collect();
        Self { least, first }
    }

    /// The sRGB byte of linear value `x` (clamped to [0, 1]; NaN reads 0).
    pub fn byte(&self, x: f32) -> u8 {
        if x.is_nan() || x <= 0.0 {
            return 0;
        }
        if x >= 1.0 {
            return 255;
        }
        let mut b = self.first[(x.to_bits() >> 16) as usize];
        // The first step without a branch (whether a run's float passes its first threshold
        // is a coin toss to the branch predictor); the loop after it is rarely entered.
        b += u8::from(self.least[usize::from(b)] <= x);
        while self.least[usize::from(b)] <= x {
            b += 1;
        }
        b
    }
}

/// The run (top 16 bits) of 1.0, the last the table needs.
const RUN_OF_ONE: u32 = 1.0f32.to_bits() >> 16;

impl Default for SrgbBytes {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_gives_the_formulas_byte_on_a_dense_sweep() {
        let table = SrgbBytes::new();
        let one = 1.0f32.to_bits();
        for bits in (0..=one).step_by(997) {
            let x = f32::from_bits(bits);
            assert_eq!(table.byte(x), to_byte(linear_to_srgb(x)), "x = {x:e}");
        }
        for x in [0.0f32, 1.0, -0.5, 2.0, 0.003_130_8, 0.5] {
            assert_eq!(table.byte(x), to_byte(linear_to_srgb(x)), "x = {x:e}");
        }
        assert_eq!(table.byte(f32::NAN), 0);
    }

    #[test]
    fn the_table_agrees_on_either_side_of_every_step() {
        let table = SrgbBytes::new();
        for &t in &table.least[..255] {
            for x in [
                f32::from_bits(t.to_bits() - 1),
                t,
                f32::from_bits(t.to_bits() + 1),
            ] {
                assert_eq!(table.byte(x), to_byte(linear_to_srgb(x)), "x = {x:e}");
            }
        }
    }
}
