//! TRELLIS.2's flexible dual grid in o_voxel's npz layout (`coord`, `vertices`,
//! `intersected`), computed from the stored grid by [`sparcubes::layouts::trellis2`].

use crate::{identity_arrays, npz::Array, npz_file, Item, ItemExport, Result};
use sparcubes::layouts::trellis2;

/// `--help` line.
pub const ABOUT: &str = "TRELLIS.2's flexible dual grid: coord, vertices, intersected";

/// One `<stem>.npz` with `coord`, `vertices` and `intersected`.
pub fn files(item: &Item) -> Result<ItemExport> {
    let g = trellis2::dual_grid(item.cubes);
    let coord: Vec<u16> = g.voxels.iter().flatten().copied().collect();
    let vertices: Vec<u8> = g.quantized.iter().flatten().copied().collect();
    let mut arrays = identity_arrays(item);
    arrays.extend([
        Array::numbers("coord", "<u2", vec![g.voxels.len(), 3], &coord),
        Array::numbers("vertices", "|u1", vec![g.voxels.len(), 3], &vertices),
        Array::numbers(
            "intersected",
            "|u1",
            vec![g.voxels.len(), 1],
            &g.intersected,
        ),
    ]);
    Ok(ItemExport {
        files: vec![npz_file(format!("{}.npz", item.stem), &arrays)?],
        ..Default::default()
    })
}
