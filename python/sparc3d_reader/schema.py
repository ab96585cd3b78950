"""What the reader shares with the `sparc3d` binary: the shard schema (docs/FORMAT.md) and the
names of `sparc3d export`'s formats.

These are copies of the Rust crates' constants (`schema`: `SCHEMA_VERSION`, `meta_keys`,
`columns`; the `--format` values of `sparc3d export`), kept in this one module so that a change
on the Rust side has one place to go here. tests/python/test_reader_constants.py checks every
one against a shard `sparc3d` has just written and against the binary's own output
(`sparc3d inspect --json`, `sparc3d show --tensors-json`, `sparc3d export --help`).
"""

from __future__ import annotations

from typing import Iterable, List

import numpy as np

#: The shard schema version this reader decodes (docs/FORMAT.md).
SCHEMA_VERSION = 3

#: Parquet footer key holding the schema version (`schema::meta_keys::SCHEMA_VERSION`).
META_SCHEMA_VERSION = "sparc3d.schema_version"
#: Parquet footer key holding the job config as JSON (`schema::meta_keys::CONFIG`).
META_CONFIG = "sparc3d.config"
#: Parquet footer key holding the config fingerprint (`schema::meta_keys::FINGERPRINT`).
META_FINGERPRINT = "sparc3d.fingerprint"

#: Tensor columns and the dtype the reader returns them in.
TENSORS = {
    "coords": np.int32,
    "sdf": np.float32,
    "deformation": np.float32,
    "cells": np.int32,
}

#: Tensor columns of a shard that the reader leaves alone: the extracted mesh, stored only
#: with `store_mesh = true` (`schema::columns::CUBE_TENSORS` after the cube tensors).
UNREAD_TENSORS = ("mesh_vertices", "mesh_faces")

#: Metadata columns copied into every item.
META_COLUMNS = ["item_index", "id", "uri", "status", "resolution",
                "center_x", "center_y", "center_z", "scale"]

#: The values of the `status` column.
STATUSES = ("ok", "failed", "skipped")

#: Vector-set sample columns (docs/FORMAT.md, "Samples"), present when the job has `[samples]`;
#: the last ones, OPTIONAL_SAMPLE_TENSORS, only where the job draws that kind.
SAMPLE_TENSORS = ["surface_points", "surface_normals", "sharp_points", "sharp_normals",
                  "near_points", "near_sdf", "volume_points", "volume_sdf", "volume_occupancy",
                  "sharp_near_points", "sharp_near_sdf"]

#: Sample columns of kinds added later: absent from older shards, null in rows of jobs that
#: draw none of them (`sharp_near = 0`, every job from before the kind existed).
OPTIONAL_SAMPLE_TENSORS = ["sharp_near_points", "sharp_near_sdf"]

#: Prefix of the provenance columns: the manifest's own columns (licence, source, name, ...),
#: strings, null where an item's row had no value (docs/FORMAT.md, "Provenance columns").
PROVENANCE_PREFIX = "manifest."

#: Exports this package reads back (`iter_export`, `ExportDataset`, the `collate_*` functions):
#: one `<index>-<stem>.npz` per item in our layouts.
EXPORT_FORMATS = ("vecset-npz", "direct3d-s2", "cubvh")
#: Exports in another codebase's own layout, read by that codebase's loader (docs/FORMAT.md,
#: "Exports"); `run_export` writes them too. With EXPORT_FORMATS: every `sparc3d export --format`.
CONSUMER_FORMATS = ("hunyuan3d-2.1", "dora", "step1x-3d", "triposg", "trellis2")


def tensor_columns(tensors: Iterable[str]) -> List[str]:
    """The three columns each tensor is stored in: `<name>`, `<name>_dtype`, `<name>_shape`."""
    return [f"{t}{s}" for t in tensors for s in ("", "_dtype", "_shape")]


#: The columns an item is read from (metadata and cube tensors).
READ_COLUMNS = META_COLUMNS + tensor_columns(TENSORS)
#: The sample columns every row with samples has.
SAMPLE_COLUMNS = tensor_columns(t for t in SAMPLE_TENSORS if t not in OPTIONAL_SAMPLE_TENSORS)
#: The sample columns of the optional kinds (read where the shard has them).
OPTIONAL_SAMPLE_COLUMNS = tensor_columns(OPTIONAL_SAMPLE_TENSORS)

#: Appearance per active cell (docs/FORMAT.md, "Attributes"), present when the job has
#: `[attributes] enabled = true`: one row per row of `cells`, uint8 (base colour sRGB [m, 3];
#: metallic, roughness, alpha [m], 0-255 for 0-1).
ATTRIBUTE_TENSORS = ["base_color", "metallic", "roughness", "alpha"]
#: The per-item facts stored beside the attributes (docs/FORMAT.md, "Attributes").
APPEARANCE_COLUMNS = ["materials", "textured", "textures", "texture_max_size", "alpha_modes",
                      "vertex_colors", "appearance_not_read", "attribute_nearest_cells"]
#: Every column of the attributes (read where the shard has them all).
ATTRIBUTE_COLUMNS = tensor_columns(ATTRIBUTE_TENSORS) + APPEARANCE_COLUMNS

#: What the conversion measured of each item (docs/FORMAT.md, "Quality columns"), in column
#: order: present when the job has `quality = true` (every job made since they exist), after
#: the tensors and attribute columns; null in failed rows. Each item holds them as scalars.
QUALITY_COLUMNS = ["input_boundary_edges", "input_non_manifold_edges", "input_degenerate_faces",
                   "input_duplicate_faces", "extent_x", "extent_y", "extent_z", "aspect",
                   "surface_area", "output_volume", "shell_share", "sealed_pockets",
                   "output_components"]

#: The output's shape signature (docs/FORMAT.md, "Shape signature"): 32 float32 per ok row,
#: present when the job has `shape_signature = true` (every job made since it exists), after
#: the quality columns; null in failed rows. Each item holds it as a float32 array [32].
SHAPE_SIGNATURE_COLUMN = "shape_signature"
