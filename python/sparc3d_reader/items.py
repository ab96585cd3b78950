"""Shard rows as items: per-item numpy tensors with their metadata, provenance and samples."""

from __future__ import annotations

from typing import Any, Dict, Iterable, Iterator, List, Union

import numpy as np
import pyarrow.parquet as pq

from . import location, row_checks
from .records import Verify
from .schema import (APPEARANCE_COLUMNS, ATTRIBUTE_COLUMNS, ATTRIBUTE_TENSORS,
                     OPTIONAL_SAMPLE_COLUMNS, OPTIONAL_SAMPLE_TENSORS, PROVENANCE_PREFIX,
                     QUALITY_COLUMNS, READ_COLUMNS, SAMPLE_COLUMNS, SAMPLE_TENSORS,
                     SHAPE_SIGNATURE_COLUMN, TENSORS)
from .shards import (PathLike, all_shards, check_row_count, check_version, naming, take_file,
                     usable)
from .tensors import decode_tensor


def row_to_item(row: Dict[str, Any]) -> Dict[str, Any]:
    """One `ok` row (a dict of column values) as an item: metadata plus the tensors in the
    reader's dtypes (coords and cells int32 [K, 3], sdf float32 [K], deformation float32 [K, 3]).
    A ValueError names the columns the row lacks."""
    missing = [c for c in READ_COLUMNS if c not in row]
    if missing:
        raise ValueError(f"item {row.get('id')!r}: no column {', '.join(map(repr, missing))} "
                         "(docs/FORMAT.md, \"Columns\")")
    item: Dict[str, Any] = {
        "id": row["id"],
        "item_index": int(row["item_index"]),
        "uri": row["uri"],
        "resolution": int(row["resolution"]),
        "center": np.array([row["center_x"], row["center_y"], row["center_z"]], dtype=np.float64),
        "scale": float(row["scale"]),
    }
    for name in QUALITY_COLUMNS:  # where the shard has them (docs/FORMAT.md, "Quality columns")
        if name in row:
            item[name] = row[name]
    if row.get(SHAPE_SIGNATURE_COLUMN) is not None:  # docs/FORMAT.md, "Shape signature"
        item[SHAPE_SIGNATURE_COLUMN] = np.array(row[SHAPE_SIGNATURE_COLUMN], dtype=np.float32)
    for name, dtype in TENSORS.items():
        t = decode_tensor(row, name)
        if t is None:
            raise ValueError(f"item {row['id']!r}: column {name!r} is empty")
        if name in ("coords", "deformation", "cells"):
            t = t.reshape(-1, 3)
        item[name] = t.astype(dtype, copy=True)
    provenance = {k[len(PROVENANCE_PREFIX):]: v for k, v in row.items()
                  if k.startswith(PROVENANCE_PREFIX)}
    if provenance:
        item["manifest"] = provenance
    if row.get("base_color") is not None:
        _add_attributes(item, row)
    if row.get("surface_points") is not None:
        item["samples"] = {name: decode_tensor(row, name) for name in SAMPLE_TENSORS
                           if name not in OPTIONAL_SAMPLE_TENSORS or row.get(name) is not None}
    return item


def _add_attributes(item: Dict[str, Any], row: Dict[str, Any]) -> None:
    """The attribute arrays (uint8, one row per row of `cells`) and the appearance facts."""
    m = len(item["cells"])
    for name in ATTRIBUTE_TENSORS:
        t = decode_tensor(row, name)
        t = t.reshape(-1, 3) if name == "base_color" else t.reshape(-1)
        if len(t) != m:
            raise ValueError(f"item {row['id']!r}: column {name!r} has {len(t)} rows, "
                             f"cells has {m}")
        item[name] = t.astype(np.uint8, copy=False)
    facts = {c: row.get(c) for c in APPEARANCE_COLUMNS}
    facts["alpha_modes"] = [x for x in (facts["alpha_modes"] or "").split(",") if x]
    facts["appearance_not_read"] = [x for x in (facts["appearance_not_read"] or "").split("\n") if x]
    item["appearance"] = facts


def samples_to_source(item: Dict[str, Any]) -> Dict[str, np.ndarray]:
    """The item's samples in the source mesh's frame (float32): points map as
    `source = p / (2 * scale) + center`, distances as `d / (2 * scale)`; normals and
    occupancy are unchanged."""
    s, center, scale = item["samples"], item["center"], item["scale"]
    out = {}
    for name, v in s.items():
        v = np.asarray(v)
        if name.endswith("_points"):
            out[name] = (v.astype(np.float64) / (2.0 * scale) + center).astype(np.float32)
        elif name.endswith("_sdf"):
            out[name] = (v.astype(np.float64) / (2.0 * scale)).astype(np.float32)
        else:
            out[name] = v.copy()
    return out


def item_columns(path: location.Location, f: pq.ParquetFile, samples: bool) -> List[str]:
    """The columns an item is read from; a ValueError names any the file lacks. The sample
    columns are read when asked for and present (jobs without `[samples]` hold them empty)."""
    check_version(path, f)
    names = f.schema_arrow.names
    row_checks.require_columns(path, names, READ_COLUMNS)
    base = READ_COLUMNS + [c for c in names if c.startswith(PROVENANCE_PREFIX)]
    if all(c in names for c in ATTRIBUTE_COLUMNS):
        base = base + ATTRIBUTE_COLUMNS
    if all(c in names for c in QUALITY_COLUMNS):
        base = base + QUALITY_COLUMNS
    if SHAPE_SIGNATURE_COLUMN in names:
        base = base + [SHAPE_SIGNATURE_COLUMN]
    if not (samples and all(c in names for c in SAMPLE_COLUMNS)):
        return base
    return base + SAMPLE_COLUMNS + [c for c in OPTIONAL_SAMPLE_COLUMNS if c in names]


def _rows(path: location.Location, f: pq.ParquetFile, batch_size: int,
          samples: bool = True) -> Iterator[Dict[str, Any]]:
    """Every row of the shard file `f` (opened from `path`), as dicts of the item columns,
    `batch_size` at a time."""
    columns = item_columns(path, f, samples)
    n = 0
    for batch in f.iter_batches(batch_size=batch_size, columns=columns):
        n += batch.num_rows
        yield from batch.to_pylist()
    check_row_count(path, n, f.metadata.num_rows)


def shard_item(path: location.Location, row: Dict[str, Any]) -> Dict[str, Any]:
    """`row_to_item`, its errors naming the shard file."""
    try:
        return row_to_item(row)
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from None


def iter_items(paths: Union[PathLike, Iterable[PathLike]], complete_only: bool = True,
               batch_size: int = 16, samples: bool = True,
               verify: Verify = True) -> Iterator[Dict[str, Any]]:
    """Yields every `ok` item of the given jobs / shard files, in shard and item order
    (failed and skipped rows are left out). Reads `batch_size` rows at a time; with
    `samples=False` the sample columns are not read.

    Each shard is checked before its first item is yielded, as `shard_paths` says (`verify`:
    True, "quick" or False); one that fails is left out with a `ShardWarning`."""
    for shard in all_shards(paths, complete_only):
        if not usable(shard, verify):
            continue
        with naming(shard.path):
            for row in _rows(shard.path, take_file(shard), batch_size, samples):
                if row["status"] == "ok":
                    yield shard_item(shard.path, row)
