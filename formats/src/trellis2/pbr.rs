//! TRELLIS.2's PBR voxels, what its texture SC-VAE trains on, as its `SparseVoxelPbrDataset`
//! (`trellis2/datasets/sparse_voxel_pbr.py` of microsoft/TRELLIS.2) reads them, written on the
//! voxels of the item's dual grid:
//!
//! - `pbr_voxels_<G>/<sha256>.vxz` (the folder `data_toolkit/voxelize_pbr.py`
//!   `_pbr_voxelize` writes, L24 and L76): o_voxel's container ([`crate::vxz`]) with the
//!   attributes `base_color` (3 × `u8`), `metallic`, `roughness`, `alpha` (1 × `u8` each), in
//!   that order: what `blender_dump_to_volumetric_attr` returns
//!   (`o-voxel/o_voxel/convert/volumetic_attr.py` L574-580) less the `normal` and `emissive`
//!   that `_pbr_voxelize` deletes (L74-75). The dataset takes them by name in its `attrs`
//!   order and maps each byte to `b / 255 · 2 − 1` (`read_pbr_voxel`, L255-262); the texture
//!   VAE's config (`configs/scvae/tex_vae_next_dc_f16c32_fp16.json`) asks for these four.
//! - Values: the shard's attribute columns as stored, one voxel per cell: base colour as sRGB
//!   bytes, metallic, roughness and alpha as bytes of [0, 1]. TRELLIS.2 samples the texture
//!   bytes as stored (`o-voxel/src/convert/volumetic_attr.cpp` `sample_texture`, L210-248:
//!   `texel / 255`), so its base colours are sRGB bytes too, and its decoder's output becomes
//!   a glTF `baseColorTexture` (`o-voxel/o_voxel/postprocess.py` `to_glb`, L297), read as sRGB.
//! - The voxels are exactly the dual grid's (`dual_grid_<G>/<sha256>.vxz` of the same item),
//!   each with the row of `cells` at the same cell: the texture flow's dataset asserts that
//!   the shape and material latents share their coordinates
//!   (`trellis2/datasets/structured_latent_svpbr.py` `SLatPbr.get_instance`, L249), and the
//!   encoders map equal voxel sets to equal latent sets. Every dual grid voxel is a row of
//!   `cells` (both are the cells with a sign change, [`sparcubes::SparseCubes`]); a voxel
//!   without one fails the item.
//! - `pbr_voxels_<G>/metadata.csv`: `sha256,pbr_voxelized,num_pbr_voxels`, the columns
//!   `_pbr_voxelize` records (L163-167) and `filter_metadata` reads (L145-158); one row per
//!   item written with PBR voxels.
//! - `data_dir.json`: the folder as `pbr_voxel` (TRELLIS.2's README, texture SC-VAE, L249).
//!
//! An item whose row holds no attributes (a job without `[attributes]`) gets no PBR file,
//! counted by the export as a note ([`NO_ATTRIBUTES`]).

use super::csv;
use crate::vxz::{self, Attr};
use crate::{Error, ExportFile, Listed, Result};
use sparcubes::attributes::CellAttributes;
use std::path::{Path, PathBuf};

/// The folder of the PBR voxels of grid size `size` (`voxelize_pbr.py` L24).
pub fn folder(size: u32) -> PathBuf {
    PathBuf::from(format!("{FOLDER_PREFIX}{size}"))
}

/// What every PBR folder's name starts with.
const FOLDER_PREFIX: &str = "pbr_voxels_";

/// The key of the PBR folder in `data_dir.json` (`get_instance`'s `root['pbr_voxel']`).
pub const DATA_DIR_KEY: &str = "pbr_voxel";

/// The listing column holding an item's voxel count; present only for items written with PBR
/// voxels.
pub const COUNT_COLUMN: &str = "num_pbr_voxels";

/// The export's note for an item written without PBR voxels.
pub const NO_ATTRIBUTES: &str =
    "without pbr_voxels (the job samples no appearance: config section [attributes])";

/// The `.vxz` of an item's PBR voxels: `voxels` are the dual grid's voxels as cells of the job
/// (sorted or not), `coords` the same voxels as written in the dual grid file, `cells` and
/// `attributes` the job's rows. Refuses attributes of another length than `cells` and a voxel
/// that is no cell.
pub fn file(
    cells: &[[u16; 3]],
    attributes: &CellAttributes,
    voxels: &[[u16; 3]],
    coords: &[[u32; 3]],
    size: u32,
    key: &str,
) -> Result<ExportFile> {
    let rows = cell_rows(cells, attributes, voxels)?;
    let base_color: Vec<u8> = rows
        .iter()
        .flat_map(|&r| attributes.base_color[r])
        .collect();
    let pick = |column: &[u8]| -> Vec<u8> { rows.iter().map(|&r| column[r]).collect() };
    let (metallic, roughness, alpha) = (
        pick(&attributes.metallic),
        pick(&attributes.roughness),
        pick(&attributes.alpha),
    );
    let attrs = [
        Attr {
            name: "base_color",
            channels: 3,
            data: &base_color,
        },
        Attr {
            name: "metallic",
            channels: 1,
            data: &metallic,
        },
        Attr {
            name: "roughness",
            channels: 1,
            data: &roughness,
        },
        Attr {
            name: "alpha",
            channels: 1,
            data: &alpha,
        },
    ];
    Ok(ExportFile {
        path: folder(size).join(format!("{key}.vxz")),
        bytes: vxz::vxz_bytes(coords, &attrs, vxz::CHUNK_SIZE)?,
    })
}

/// The row of `cells` of each voxel; refuses attributes of another length than `cells` and a
/// voxel that is no cell.
fn cell_rows(
    cells: &[[u16; 3]],
    attributes: &CellAttributes,
    voxels: &[[u16; 3]],
) -> Result<Vec<usize>> {
    let lengths = [
        attributes.base_color.len(),
        attributes.metallic.len(),
        attributes.roughness.len(),
        attributes.alpha.len(),
    ];
    if lengths != [cells.len(); 4] {
        return Err(Error::Invalid(format!(
            "the attribute columns hold {lengths:?} rows (base_color, metallic, roughness, \
             alpha) for {} cells",
            cells.len()
        )));
    }
    voxels
        .iter()
        .map(|v| {
            cells.binary_search(v).map_err(|_| {
                Error::Invalid(format!(
                    "dual grid voxel {v:?} is no active cell, so it has no attributes"
                ))
            })
        })
        .collect()
}

/// The PBR folder (relative) and its `metadata.csv`, when any item was written with PBR
/// voxels: one row per such item (in item order), `pbr_voxelized` `True`.
pub fn listing(items: &[Listed]) -> Option<(PathBuf, ExportFile)> {
    let with: Vec<&Listed> = items
        .iter()
        .filter(|i| i.columns.contains_key(COUNT_COLUMN))
        .collect();
    let dir = with.iter().find_map(|i| {
        i.files
            .iter()
            .filter_map(|f| f.parent())
            .find(|d| d.to_string_lossy().starts_with(FOLDER_PREFIX))
            .map(Path::to_path_buf)
    })?;
    let col = |i: &Listed, k: &str| i.columns.get(k).cloned().unwrap_or_default();
    let rows = with
        .iter()
        .map(|i| vec![col(i, "sha256"), "True".into(), col(i, COUNT_COLUMN)]);
    let table = ExportFile {
        path: dir.join("metadata.csv"),
        bytes: csv("sha256,pbr_voxelized,num_pbr_voxels", rows).into_bytes(),
    };
    Some((dir, table))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn attributes(n: u8) -> CellAttributes {
        CellAttributes {
            base_color: (0..n).map(|i| [i, 10 + i, 20 + i]).collect(),
            metallic: (0..n).map(|i| 30 + i).collect(),
            roughness: (0..n).map(|i| 40 + i).collect(),
            alpha: (0..n).map(|i| 50 + i).collect(),
            nearest_cells: 0,
        }
    }

    #[test]
    fn each_voxel_takes_the_row_of_its_cell() {
        let cells = [[1, 1, 1], [1, 2, 1], [4, 0, 0]];
        let a = attributes(3);
        // Voxels given out of cell order, moved into the export grid by −1.
        let voxels = [[4, 0, 0], [1, 1, 1]];
        let rows = cell_rows(&cells, &a, &voxels).unwrap_or_default();
        assert_eq!(rows, vec![2, 0]);
        let f = file(&cells, &a, &voxels, &[[3, 0, 0], [0, 0, 0]], 8, "ab");
        let f = f.unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(f.path, PathBuf::from("pbr_voxels_8/ab.vxz"));
        let start = u32::from_be_bytes([f.bytes[4], f.bytes[5], f.bytes[6], f.bytes[7]]);
        let header: serde_json::Value =
            serde_json::from_slice(&f.bytes[8..start as usize]).unwrap_or_default();
        assert_eq!(
            header["attr"],
            serde_json::json!([
                ["base_color", 3],
                ["metallic", 1],
                ["roughness", 1],
                ["alpha", 1]
            ])
        );
        assert_eq!(header["num_voxel"], 2);
    }

    #[test]
    fn a_voxel_without_a_cell_or_misshapen_columns_are_refused() {
        let cells = [[1, 1, 1], [1, 2, 1]];
        assert!(cell_rows(&cells, &attributes(2), &[[0, 0, 0]]).is_err());
        assert!(cell_rows(&cells, &attributes(3), &[[1, 1, 1]]).is_err());
        let mut short = attributes(2);
        short.alpha.pop();
        assert!(cell_rows(&cells, &short, &[[1, 1, 1]]).is_err());
    }

    #[test]
    fn the_listing_has_a_row_per_item_with_pbr_voxels() {
        let listed = |id: &str, pbr: bool| Listed {
            id: id.into(),
            stem: id.into(),
            files: [
                Some(PathBuf::from("dual_grid_8/x.vxz")),
                pbr.then(|| PathBuf::from(format!("pbr_voxels_8/{id}.vxz"))),
            ]
            .into_iter()
            .flatten()
            .collect(),
            columns: BTreeMap::from_iter(
                [("sha256", id), (COUNT_COLUMN, "5")]
                    .into_iter()
                    .take(if pbr { 2 } else { 1 })
                    .map(|(k, v)| (k.to_string(), v.to_string())),
            ),
            provenance: BTreeMap::new(),
        };
        assert_eq!(listing(&[listed("a", false)]), None);
        let (dir, table) = listing(&[listed("a", false), listed("b", true)]).unwrap_or_else(|| {
            panic!("no listing");
        });
        assert_eq!(dir, PathBuf::from("pbr_voxels_8"));
        assert_eq!(table.path, PathBuf::from("pbr_voxels_8/metadata.csv"));
        assert_eq!(
            String::from_utf8_lossy(&table.bytes),
            "sha256,pbr_voxelized,num_pbr_voxels\nb,True,5\n"
        );
    }
}
