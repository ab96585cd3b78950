//! cubvh's sparse voxels (`cubvh.sparse_marching_cubes` inputs): the active cells, each packed
//! as `(x·N + y)·N + z` in a `u64`, and the 8 corner values of each as sign + magnitude bytes
//! packed in a `u64` ([`sparcubes::layouts::cubvh`] computes them from the stored grid).

use crate::{identity_arrays, npz::Array, npz_file, Item, ItemExport, Result};

/// `--help` line.
pub const ABOUT: &str = "cubvh's sparse voxels: <item>.npz (active_cells, active_cells_sdf, packed u64); checked against test/sparse_voxel.py";

/// One `<stem>.npz` with `active_cells` and `active_cells_sdf`.
pub fn files(item: &Item) -> Result<ItemExport> {
    let n = item.cubes.resolution as u64;
    let v = sparcubes::layouts::cubvh::cubvh_voxels(item.cubes);
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
