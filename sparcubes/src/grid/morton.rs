//! Morton (Z-order) codes of 3D cells: the bits of the three coordinates interleaved, so that
//! sorting by code keeps nearby cells nearby. The closest-point tree ([`crate::queries::closest`]) and
//! the winding-number tree ([`crate::queries::winding`]) sort their triangles by these codes.

/// Bits per coordinate of a code (three of them fill 63 bits of a `u64`).
pub const BITS: u32 = 21;

/// The Morton code of `cell`: bit `b` of coordinate `a` at bit `3·b + a` (x lowest); only the
/// low [`BITS`] bits of each coordinate count.
#[inline]
pub fn code(cell: [u64; 3]) -> u64 {
    spread(cell[0]) | (spread(cell[1]) << 1) | (spread(cell[2]) << 2)
}

/// The low [`BITS`] bits of `v` spread to every third bit of a `u64`.
#[inline]
fn spread(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn code_interleaves_the_bits_x_lowest() {
        // Against a bit-by-bit interleave.
        let slow = |c: [u64; 3]| -> u64 {
            (0..BITS as u64)
                .flat_map(|b| (0..3).map(move |a| (a, b)))
                .map(|(a, b)| ((c[a as usize] >> b) & 1) << (3 * b + a))
                .sum()
        };
        let top = (1u64 << BITS) - 1;
        for c in [
            [0, 0, 0],
            [1, 0, 0],
            [0, 1, 0],
            [0, 0, 1],
            [top, 0, 5],
            [top, top, top],
        ] {
            assert_eq!(code(c), slow(c), "{c:?}");
        }
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..1000 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let c = [state & top, (state >> 21) & top, (state >> 42) & top];
            assert_eq!(code(c), slow(c), "{c:?}");
        }
        // Bits above BITS are ignored.
        assert_eq!(code([top + 1, 0, 0]), 0);
    }
}
