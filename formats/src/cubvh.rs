//! cubvh's sparse voxels (`cubvh.sparse_marching_cubes` inputs): the active cells, each packed
//! as `(x·N + y)·N + z` in a `u64`, and the 8 corner values of each as sign + magnitude bytes
//! packed in a `u64`, from the corner values of the stored grid
//! ([`sparcubes::products::corners`]).
//!
//! cubvh's encoding (`test/sparse_voxel.py` of ashawkey/cubvh): the active cells (a sign change
//! among their corners) with their 8 corner values in marching-cubes order (000, 100, 110,
//! 010, 001, 101, 111, 011 as x, y, z offsets, [`CORNER_ORDER`]), each a byte: bit 7 set when
//! the value is negative (inside), bits 0–6 `rint(min(|φ| / δ, 127))` with δ = √3 voxels / 127
//! (in cubvh's [−1, 1] frame, δ = 2/N · √3 / 127, [`encode`]). Stored files pack a cell's 8
//! bytes into a little-endian `u64` (corner 0 in the low byte) and the cell as `x·N² + y·N + z`.

use crate::spec::{grid_views, needs_no_samples, no_listing, takes_any_job, Reads, Spec, Views};
use crate::Frame;
use crate::{identity_arrays, npz::Array, npz_file, Item, ItemExport, Result};
use sparcubes::products::corners::corner_values;
use sparcubes::SparseCubes;

/// `--help` line.
pub const ABOUT: &str = "cubvh's sparse voxels: <item>.npz (active_cells, active_cells_sdf, packed u64); checked against test/sparse_voxel.py";

/// cubvh as the export, `--for` and `--help` know it.
pub const SPEC: Spec = Spec {
    name: "cubvh",
    title: "cubvh",
    about: ABOUT,
    frames: &[Frame::Consumer],
    reads: Reads::CUBES,
    // It reads any job: no preset.
    preset: None,
    missing: needs_no_samples,
    check: takes_any_job,
    files,
    views: Views::Plain(grid_views),
    listing: no_listing,
};

/// One `<stem>.npz` with `active_cells` and `active_cells_sdf`.
pub fn files(item: &Item) -> Result<ItemExport> {
    let n = item.cubes.resolution as u64;
    let v = cubvh_voxels(item.cubes);
    let cells: Vec<u64> = v
        .cells
        .iter()
        .map(|c| (c[0] as u64 * n + c[1] as u64) * n + c[2] as u64)
        .collect();
    let codes: Vec<u64> = v.codes.iter().map(|c| u64::from_le_bytes(*c)).collect();
    let mut arrays = identity_arrays(item);
    arrays.extend([
        Array::numbers("active_cells", "<u8", vec![cells.len()], &cells),
        Array::numbers("active_cells_sdf", "<u8", vec![codes.len()], &codes),
    ]);
    Ok(ItemExport {
        files: vec![npz_file(format!("{}.npz", item.stem), &arrays)?],
        ..Default::default()
    })
}

/// The corner order of cubvh, as (x, y, z) offsets.
pub const CORNER_ORDER: [[u16; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [1, 1, 0],
    [0, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [1, 1, 1],
    [0, 1, 1],
];

/// cubvh's sparse voxels of one item.
#[derive(Debug, Clone, Default, PartialEq)]
struct CubvhVoxels {
    /// Active cells by minimum corner, sorted.
    cells: Vec<[u16; 3]>,
    /// Per cell, the sign + magnitude byte of each corner in [`CORNER_ORDER`].
    codes: Vec<[u8; 8]>,
}

/// The code of a value `phi` in voxels.
#[inline]
pub fn encode(phi: f32) -> u8 {
    let mag = (phi.abs() as f64 * 127.0 / 3f64.sqrt())
        .clamp(0.0, 127.0)
        .round_ties_even() as u8;
    if phi < 0.0 {
        0x80 | mag
    } else {
        mag
    }
}

/// The value in voxels of a code (the inverse of [`encode`] up to rounding).
#[inline]
pub fn decode(code: u8) -> f32 {
    let mag = (code & 0x7f) as f64 * 3f64.sqrt() / 127.0;
    (if code & 0x80 != 0 { -mag } else { mag }) as f32
}

/// cubvh's layout of `cubes` (cells whose corners are not all stored are skipped).
fn cubvh_voxels(cubes: &SparseCubes) -> CubvhVoxels {
    let corners = corner_values(cubes);
    let codes = corners
        .values
        .iter()
        .map(|values| {
            // Our corner k sits at (k & 1, k >> 1 & 1, k >> 2); cubvh's order is CORNER_ORDER.
            CORNER_ORDER.map(|o| encode(values[usize::from(o[0] | (o[1] << 1) | (o[2] << 2))]))
        })
        .collect();
    CubvhVoxels {
        cells: corners.cells,
        codes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sparcubes::extract::sample_box;

    #[test]
    fn codes_follow_cubvh_quantisation_and_corner_order() {
        assert_eq!(encode(0.0), 0);
        assert_eq!(encode(-0.0), 0);
        assert_eq!(encode(3f32.sqrt()), 127);
        assert_eq!(encode(-10.0), 0x80 | 127);
        assert_eq!(encode(-(3f32.sqrt()) / 127.0 * 5.0), 0x80 | 5);
        assert!((decode(encode(0.5)) - 0.5).abs() <= 3f32.sqrt() / 254.0 + 1e-6);
        // A plane x = 2.3: values x − 2.3 on every vertex.
        let cubes = sample_box(8, [0; 3], [6; 3], |c| (c[0] as f32 - 2.3, [0.0; 3]));
        let v = cubvh_voxels(&cubes);
        assert_eq!(v.cells.len(), 36);
        for (c, codes) in v.cells.iter().zip(&v.codes) {
            assert_eq!(c[0], 2);
            for (k, o) in CORNER_ORDER.iter().enumerate() {
                let phi = (c[0] + o[0]) as f32 - 2.3;
                assert_eq!(codes[k], encode(phi));
                assert_eq!(codes[k] & 0x80 != 0, phi < 0.0);
            }
        }
    }
}
