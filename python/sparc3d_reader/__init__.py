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

Only numpy and pyarrow are needed; `SparseCubesDataset` is a `torch.utils.data.Dataset` when
torch is installed (imported only when the class is first used) and a plain indexable class
otherwise.
"""

from __future__ import annotations

import json
import os
import pathlib
from typing import Any, Dict, Iterable, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

__all__ = [
    "TENSORS",
    "shard_paths",
    "decode_tensor",
    "row_to_item",
    "iter_items",
    "collate_sparse",
    "SparseCubesDataset",
]

__version__ = "0.1.0"

#: Tensor columns and the dtype the reader returns them in.
TENSORS = {
    "coords": np.int32,
    "sdf": np.float32,
    "deformation": np.float32,
    "cells": np.int32,
}

#: Metadata columns copied into every item.
META_COLUMNS = ["item_index", "id", "uri", "status", "resolution",
                "center_x", "center_y", "center_z", "scale"]

_READ_COLUMNS = META_COLUMNS + [f"{t}{s}" for t in TENSORS for s in ("", "_dtype", "_shape")]

PathLike = Union[str, os.PathLike]


def shard_paths(paths: Union[PathLike, Iterable[PathLike]], complete_only: bool = True) -> List[pathlib.Path]:
    """The shard files under `paths`: each path is a job folder (its `shards/part-*.parquet`,
    only those with a completion record unless `complete_only` is false) or a shard file."""
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    out: List[pathlib.Path] = []
    for p in paths:
        p = pathlib.Path(p)
        if p.is_dir():
            shards = p / "shards" if (p / "shards").is_dir() else p
            for f in sorted(shards.glob("part-*.parquet")):
                if not complete_only or f.with_name(f.name[: -len(".parquet")] + ".complete.json").exists():
                    out.append(f)
        elif p.is_file():
            out.append(p)
        else:
            raise FileNotFoundError(f"{p}: neither a job folder nor a shard file")
    return out


#: The shard schema version this reader decodes (docs/FORMAT.md).
SCHEMA_VERSION = 3


def decode_tensor(row: Dict[str, Any], name: str) -> Optional[np.ndarray]:
    """Decodes one tensor column of a row as docs/FORMAT.md describes (None when absent): the
    zstd frame holds the elements' little-endian bytes in byte planes, column by column."""
    if row.get(name) is None:
        return None
    dtype, shape = np.dtype(row[name + "_dtype"]), row[name + "_shape"]
    n, k = int(shape[0]), int(np.prod(shape[1:]))
    raw = pa.decompress(row[name], decompressed_size=n * k * dtype.itemsize, codec="zstd")
    planes = np.frombuffer(raw, np.uint8).reshape(k, dtype.itemsize, n)
    return planes.transpose(2, 0, 1).copy().view(dtype).reshape(shape)


def row_to_item(row: Dict[str, Any]) -> Dict[str, Any]:
    """One `ok` row (a dict of column values) as an item: metadata plus the tensors in the
    reader's dtypes (coords and cells int32 [K, 3], sdf float32 [K], deformation float32 [K, 3])."""
    item: Dict[str, Any] = {
        "id": row["id"],
        "item_index": int(row["item_index"]),
        "uri": row["uri"],
        "resolution": int(row["resolution"]),
        "center": np.array([row["center_x"], row["center_y"], row["center_z"]], dtype=np.float64),
        "scale": float(row["scale"]),
    }
    for name, dtype in TENSORS.items():
        t = decode_tensor(row, name)
        if t is None:
            raise ValueError(f"item {row['id']!r}: column {name!r} is empty")
        if name in ("coords", "deformation", "cells"):
            t = t.reshape(-1, 3)
        item[name] = t.astype(dtype, copy=True)
    return item


def _rows(path: pathlib.Path, batch_size: int) -> Iterator[Dict[str, Any]]:
    f = pq.ParquetFile(path)
    meta = f.metadata.metadata or {}
    version = meta.get(b"sparc3d.schema_version", b"missing").decode()
    if version != str(SCHEMA_VERSION):
        raise ValueError(f"{path}: shard schema version {version}, this reader decodes "
                         f"version {SCHEMA_VERSION} (docs/FORMAT.md)")
    for batch in f.iter_batches(batch_size=batch_size, columns=_READ_COLUMNS):
        yield from batch.to_pylist()


def iter_items(paths: Union[PathLike, Iterable[PathLike]], complete_only: bool = True,
               batch_size: int = 16) -> Iterator[Dict[str, Any]]:
    """Yields every `ok` item of the given jobs / shard files, in shard and item order
    (failed and skipped rows are left out). Reads `batch_size` rows at a time."""
    for path in shard_paths(paths, complete_only):
        for row in _rows(path, batch_size):
            if row["status"] == "ok":
                yield row_to_item(row)


def collate_sparse(batch: Sequence[Dict[str, Any]], to_torch: bool = False) -> Dict[str, Any]:
    """Concatenates items into the layout sparse-convolution libraries expect:

    - `coords` int32 [ΣK, 4]: batch index, x, y, z
    - `feats` float32 [ΣK, 4]: sdf, deformation x, y, z
    - `offsets` int64 [B + 1]: item b's rows are `offsets[b]:offsets[b + 1]`
    - `cells` int32 [ΣC, 4] (batch index + minimum corner) and `cell_offsets` int64 [B + 1]
    - `ids`, `resolution` (lists)

    With `to_torch=True` the arrays are torch tensors."""
    ks = [len(it["coords"]) for it in batch]
    cs = [len(it["cells"]) for it in batch]
    coords = np.zeros((sum(ks), 4), dtype=np.int32)
    feats = np.zeros((sum(ks), 4), dtype=np.float32)
    cells = np.zeros((sum(cs), 4), dtype=np.int32)
    offsets = np.zeros(len(batch) + 1, dtype=np.int64)
    cell_offsets = np.zeros(len(batch) + 1, dtype=np.int64)
    offsets[1:] = np.cumsum(ks)
    cell_offsets[1:] = np.cumsum(cs)
    for b, it in enumerate(batch):
        lo, hi = offsets[b], offsets[b + 1]
        coords[lo:hi, 0] = b
        coords[lo:hi, 1:] = it["coords"]
        feats[lo:hi, 0] = it["sdf"]
        feats[lo:hi, 1:] = it["deformation"]
        clo, chi = cell_offsets[b], cell_offsets[b + 1]
        cells[clo:chi, 0] = b
        cells[clo:chi, 1:] = it["cells"]
    out: Dict[str, Any] = {
        "coords": coords,
        "feats": feats,
        "offsets": offsets,
        "cells": cells,
        "cell_offsets": cell_offsets,
        "ids": [it["id"] for it in batch],
        "resolution": [it["resolution"] for it in batch],
    }
    if to_torch:
        import torch

        for k in ("coords", "feats", "offsets", "cells", "cell_offsets"):
            out[k] = torch.from_numpy(out[k])
    return out


class _SparseCubesDatasetBase:
    """Indexable items of jobs / shard files (see `iter_items` for what an item holds).

    Indexes the `ok` rows once (metadata columns only); `ds[i]` reads the row group holding
    item i (the last one read is cached, so reading in order is cheap). `transform`, when
    given, is applied to each item."""

    def __init__(self, paths: Union[PathLike, Iterable[PathLike]], complete_only: bool = True,
                 transform=None):
        self.paths = shard_paths(paths, complete_only)
        self.transform = transform
        # (shard number, row group, row within the group) of every ok row.
        self.index: List[Tuple[int, int, int]] = []
        self.ids: List[str] = []
        for s, path in enumerate(self.paths):
            f = pq.ParquetFile(path)
            for g in range(f.metadata.num_row_groups):
                t = f.read_row_group(g, columns=["id", "status"]).to_pydict()
                for r, (id_, status) in enumerate(zip(t["id"], t["status"])):
                    if status == "ok":
                        self.index.append((s, g, r))
                        self.ids.append(id_)
        self._cache: Tuple[Optional[Tuple[int, int]], Optional[pa.Table]] = (None, None)

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, i: int) -> Dict[str, Any]:
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(f"item {i} out of range ({len(self)} items)")
        s, g, r = self.index[i]
        key, table = self._cache
        if key != (s, g) or table is None:
            table = pq.ParquetFile(self.paths[s]).read_row_group(g, columns=_READ_COLUMNS)
            self._cache = ((s, g), table)
        item = row_to_item(table.slice(r, 1).to_pylist()[0])
        return self.transform(item) if self.transform else item

    def __iter__(self) -> Iterator[Dict[str, Any]]:
        for i in range(len(self)):
            yield self[i]

    def __getstate__(self):
        # Worker processes of a DataLoader get a copy without the cached row group.
        state = self.__dict__.copy()
        state["_cache"] = (None, None)
        return state


_dataset_class = None


def _make_dataset_class():
    global _dataset_class
    if _dataset_class is None:
        try:
            import torch.utils.data as tud

            bases = (_SparseCubesDatasetBase, tud.Dataset)
        except ImportError:
            bases = (_SparseCubesDatasetBase,)
        _dataset_class = type("SparseCubesDataset", bases, {
            "__doc__": _SparseCubesDatasetBase.__doc__,
            "__module__": __name__,
        })
    return _dataset_class


def __getattr__(name: str):
    # `SparseCubesDataset` is built on first use, so importing this package never imports torch.
    if name == "SparseCubesDataset":
        return _make_dataset_class()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def read_job_config(job: PathLike) -> Dict[str, Any]:
    """The config of a job folder (`job.json`'s `config`)."""
    return json.loads((pathlib.Path(job) / "job.json").read_text())["config"]
