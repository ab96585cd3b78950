"""Reads sparc3d shards (docs/FORMAT.md) into per-item sparse cube tensors.

    from sparc3d_reader import iter_items, SparseCubesDataset, collate_sparse

    for item in iter_items("job"):             # a job folder, shard files, or a list of them
        item["coords"]        # int32 [K, 3]  active grid vertices (x, y, z) in 0..=resolution
        item["sdf"]           # float32 [K]   signed distance in voxels, negative inside
        item["deformation"]   # float32 [K, 3] displacement in voxels
        item["cells"]         # int32 [C, 3]  active cells by their minimum corner

    batch = collate_sparse([item_a, item_b])
    batch["coords"]           # int32 [K_a + K_b, 4]: batch index, x, y, z
    batch["feats"]            # float32 [K_a + K_b, 4]: sdf, dx, dy, dz
    batch["corners"]          # int64 [C_a + C_b, 8]: rows of each cell's 8 corners

Tensor files (the same encoding, other columns) are written with `write_tensor_file` and read
with `iter_tensor_rows`; `sparc3d extract` reads such a file, and `sparc3d-vae` writes its
latents with it.

Jobs with `[samples]` also give `item["samples"]` (vector-set VAE samples in the normalized
frame; `samples_to_source` maps them to the source frame), batched by `collate_vecset`. The
layouts of other codebases are written by `sparc3d export` (`run_export`) and read back with
`iter_export` / `ExportDataset` and `collate_direct3d_s2`, `collate_cubvh` (TRELLIS.2's export is
its own dataset folder, read by its `FlexiDualGridDataset`). `one_per_group(items, result)` keeps
one item per near-duplicate group of `sparc3d dedup --json` (`dedup.py`).

A job folder is read as the CLI reads it (`jobs.py` and the modules it names): only its own
shards, each checked against its completion record (`verify=True`: the sha256; "quick"; False)
and its rows against the frozen manifest; every shard left out is named in a `ShardWarning`.
Wherever a job is taken, a job URL is too (`s3://bucket/prefix`, `gs://`, `az://`: a job whose
home is a bucket, read through `pyarrow.fs` with the credentials and endpoint of the
environment, `location.py`).

Only numpy and pyarrow are needed; `SparseCubesDataset` is a `torch.utils.data.Dataset` when
torch is installed (imported only when the class is first used) and a plain indexable class
otherwise. `StreamingDataset` streams a job into training (a torch `IterableDataset`): shuffled
per epoch, split exactly across ranks and DataLoader workers, resumable mid-epoch. Both take
`where="..."`, a filter on the scalar columns in the language of the binary's `--where`.

The package in modules, each with one job: `schema.py` what is shared with the Rust binary (the
schema version, column names, tensor names, export formats), `tensors.py` the tensor encoding
and tensor files, `shards.py` which files are read and the checks on each, `items.py` rows as
items, `dataset.py` the indexable dataset, `streaming.py` the streaming one (its order in
`stream_order.py`, its DataLoader in `stream_loader.py`), `where.py` filters and `selection.py`
the rows they select, `torch_classes.py` the two datasets as torch classes, `collate.py`
batches, `exports.py` other codebases' layouts, `job_file.py` a job (job.json, its frozen
manifest) and `jobs.py` the names of the checks on its shards, `job_listing.py` which of its
shards are read, `records.py` a shard against its completion record, `row_checks.py` its rows
against the manifest, `location.py` folders and bucket URLs. Everything is imported from the
package itself.
"""

from __future__ import annotations

from . import jobs, location
from .collate import CORNER_OFFSETS, collate_sparse, collate_vecset, corner_index
from .dedup import dropped_ids, one_per_group
from .exports import (ExportDataset, collate_cubvh, collate_direct3d_s2, cubvh_cells,
                      cubvh_corner_values, iter_export, run_export)
from .items import iter_items, row_to_item, samples_to_source
from .job_listing import ShardWarning
from .location import ObjectPath
from .records import Verify
from .schema import (APPEARANCE_COLUMNS, ATTRIBUTE_TENSORS, CONSUMER_FORMATS, EXPORT_FORMATS,
                     META_COLUMNS, OPTIONAL_SAMPLE_TENSORS,
                     PROVENANCE_PREFIX, QUALITY_COLUMNS, SAMPLE_TENSORS, SCHEMA_VERSION,
                     SHAPE_SIGNATURE_COLUMN, TENSORS)
from .shards import PathLike, check_schema_version, read_job_config, shard_config, shard_paths
from .tensors import (decode_tensor, encode_tensor, iter_tensor_rows, write_completion_record,
                      write_tensor_file)
from .dataset import SparseCubesDatasetBase
from .streaming import StreamingDatasetBase
from .torch_classes import torch_class as _torch_class
from .where import Where

__all__ = [
    "TENSORS",
    "SAMPLE_TENSORS",
    "ATTRIBUTE_TENSORS",
    "APPEARANCE_COLUMNS",
    "QUALITY_COLUMNS",
    "SHAPE_SIGNATURE_COLUMN",
    "OPTIONAL_SAMPLE_TENSORS",
    "samples_to_source",
    "collate_vecset",
    "run_export",
    "CONSUMER_FORMATS",
    "iter_export",
    "ExportDataset",
    "collate_direct3d_s2",
    "collate_cubvh",
    "shard_paths",
    "ShardWarning",
    "decode_tensor",
    "row_to_item",
    "iter_items",
    "collate_sparse",
    "corner_index",
    "CORNER_OFFSETS",
    "encode_tensor",
    "write_completion_record",
    "write_tensor_file",
    "iter_tensor_rows",
    "shard_config",
    "check_schema_version",
    "SparseCubesDataset",
    "StreamingDataset",
    "Where",
    "ObjectPath",
    "dropped_ids",
    "one_per_group",
]

__version__ = "0.1.0"


def __getattr__(name: str):
    # The datasets are built on first use, so importing this package never imports torch.
    if name == "SparseCubesDataset":
        return _torch_class(name, SparseCubesDatasetBase, "Dataset", __name__)
    if name == "StreamingDataset":
        return _torch_class(name, StreamingDatasetBase, "IterableDataset", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
