//! Direct3D-S2's sparse SDF (`SparseSDFVAE.encode`: `sparse_index` [N, 3], `sparse_sdf`
//! [N, 1]), computed from the stored grid by [`sparcubes::layouts::direct3d_s2`].

use crate::{identity_arrays, npz::Array, npz_file, Item, ItemExport, Result};
use sparcubes::layouts::direct3d_s2;

/// `--help` line.
pub const ABOUT: &str = "Direct3D-S2's sparse SDF: sparse_index, sparse_sdf";

/// One `<stem>.npz` with `sparse_index` and `sparse_sdf`.
pub fn files(item: &Item) -> Result<ItemExport> {
    let s = direct3d_s2::sparse_sdf(item.cubes, direct3d_s2::TRUNCATION);
    let index: Vec<i32> = s.coords.iter().flatten().map(|&c| c as i32).collect();
    let mut arrays = identity_arrays(item);
    arrays.extend([
        Array::numbers("sparse_index", "<i4", vec![s.coords.len(), 3], &index),
        Array::numbers("sparse_sdf", "<f4", vec![s.sdf.len(), 1], &s.sdf),
    ]);
    Ok(ItemExport {
        files: vec![npz_file(format!("{}.npz", item.stem), &arrays)?],
        ..Default::default()
    })
}
