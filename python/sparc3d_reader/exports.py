"""The layouts of other codebases, written by `sparc3d export` and read back here.

The geometry of every layout lives in the Rust CLI, so Python never recomputes it: `run_export`
runs the binary, `iter_export` / `ExportDataset` read the `.npz` files of our layouts
(`EXPORT_FORMATS`), and `collate_direct3d_s2`, `collate_cubvh` batch them. The consumers' own
layouts (`CONSUMER_FORMATS`, TRELLIS.2's dataset folder among them) are read by their loaders.
"""

from __future__ import annotations

import pathlib
import subprocess
from typing import Any, Dict, Iterator, Optional, Sequence

import numpy as np

from .collate import as_torch
from .schema import CONSUMER_FORMATS, EXPORT_FORMATS
from .shards import PathLike


def run_export(job: PathLike, fmt: str, out: PathLike, ids: Optional[Sequence[str]] = None,
               frame: Optional[str] = None, binary: str = "sparc3d") -> pathlib.Path:
    """Runs `sparc3d export JOB --format FMT --out OUT` (the geometry of every layout lives in
    the Rust CLI, so Python never recomputes it) and returns the output folder. `frame`: None
    for the format's own (the consumer's cube; `normalized` for vecset-npz), else `consumer`,
    `normalized` or `source`."""
    if fmt not in EXPORT_FORMATS + CONSUMER_FORMATS:
        raise ValueError(f"unknown format {fmt!r}; one of "
                         f"{', '.join(EXPORT_FORMATS + CONSUMER_FORMATS)}")
    cmd = [binary, "export", str(job), "--format", fmt, "--out", str(out)]
    if frame is not None:
        cmd += ["--frame", frame]
    if ids:
        cmd += ["--ids", ",".join(ids)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr.strip()}")
    return pathlib.Path(out)


def _load_npz(path: pathlib.Path) -> Dict[str, Any]:
    """The arrays of one exported item, with its `id` (str) and `item_index` (int)."""
    with np.load(path) as z:
        item = {k: z[k] for k in z.files}
    # Every export names its item inside (`id`, `item_index`); files of older versions did
    # not, and were named after the id.
    item["id"] = str(item["id"]) if "id" in item else path.stem
    if "item_index" in item:
        item["item_index"] = int(item["item_index"])
    return item


def iter_export(folder: PathLike) -> Iterator[Dict[str, Any]]:
    """Yields the arrays of every `.npz` in an export folder (sorted by name, which is
    manifest order), with `id` (str) and `item_index` (int) from inside the file."""
    for path in sorted(pathlib.Path(folder).glob("*.npz")):
        yield _load_npz(path)


class ExportDataset:
    """The `.npz` files of an export folder as an indexable dataset (`ds[i]` is a dict of
    arrays); works as a `torch.utils.data.Dataset` with `DataLoader` and the collate
    functions below."""

    def __init__(self, folder: PathLike, transform=None):
        self.paths = sorted(pathlib.Path(folder).glob("*.npz"))
        self.transform = transform

    def __len__(self) -> int:
        return len(self.paths)

    def __getitem__(self, i: int) -> Dict[str, Any]:
        item = _load_npz(self.paths[i])
        return self.transform(item) if self.transform else item


def _batch_coords(parts: Sequence[np.ndarray]) -> np.ndarray:
    """int32 [ΣN, 4]: batch index, then the item's (x, y, z)."""
    total = sum(len(p) for p in parts)
    out = np.zeros((total, 4), dtype=np.int32)
    lo = 0
    for b, p in enumerate(parts):
        out[lo:lo + len(p), 0] = b
        out[lo:lo + len(p), 1:] = p
        lo += len(p)
    return out


def collate_direct3d_s2(batch: Sequence[Dict[str, Any]], to_torch: bool = False) -> Dict[str, Any]:
    """Direct3D-S2 items → the batch its sparse SDF VAE encodes (`ss_vae.py` reads
    `sparse_sdf`, `sparse_index`, `batch_idx`): `sparse_sdf` float32 [ΣN, 1] in (−1, 1),
    `sparse_index` int32 [ΣN, 3], `batch_idx` int64 [ΣN], and `coords` int32 [ΣN, 4]."""
    coords = _batch_coords([np.asarray(it["sparse_index"]) for it in batch])
    out = {
        "coords": coords,
        "sparse_index": coords[:, 1:].copy(),
        "batch_idx": coords[:, 0].astype(np.int64),
        "sparse_sdf": np.concatenate([np.asarray(it["sparse_sdf"], np.float32).reshape(-1, 1)
                                      for it in batch]),
        "ids": [it.get("id") for it in batch],
    }
    return as_torch(out, to_torch)


def cubvh_cells(item: Dict[str, Any]) -> np.ndarray:
    """The cells of a cubvh item, int32 [N, 3], from its packed `active_cells`."""
    res = int(item["resolution"])
    c = np.asarray(item["active_cells"], dtype=np.uint64)
    return np.stack([c // (res * res), c // res % res, c % res], axis=1).astype(np.int32)


def _cubvh_codes(packed: np.ndarray) -> np.ndarray:
    """The 8 sign + magnitude bytes of each cell, uint8 [N, 8], from cubvh's packed u64."""
    packed = np.asarray(packed, dtype=np.uint64)
    codes = (packed[:, None] >> (np.arange(8, dtype=np.uint64) * np.uint64(8))) & np.uint64(0xFF)
    return codes.astype(np.uint8)


def cubvh_corner_values(item: Dict[str, Any]) -> np.ndarray:
    """The 8 corner values of each cubvh cell, float32 [N, 8] in voxels (cubvh's corner order
    000, 100, 110, 010, 001, 101, 111, 011; negative inside), from the packed bytes."""
    codes = _cubvh_codes(item["active_cells_sdf"])
    mag = (codes & 0x7F).astype(np.float32) * np.float32(np.sqrt(3.0) / 127.0)
    return np.where(codes & 0x80, -mag, mag).astype(np.float32)


def collate_cubvh(batch: Sequence[Dict[str, Any]], to_torch: bool = False) -> Dict[str, Any]:
    """cubvh items → `coords` int32 [ΣN, 4] (batch index first) and `corners` float32 [ΣN, 8]
    (corner values in voxels, cubvh's corner order), `codes` uint8 [ΣN, 8] (the stored sign +
    magnitude bytes)."""
    coords = _batch_coords([cubvh_cells(it) for it in batch])
    packed = np.concatenate([np.asarray(it["active_cells_sdf"], np.uint64) for it in batch])
    out = {
        "coords": coords,
        "corners": np.concatenate([cubvh_corner_values(it) for it in batch]),
        "codes": _cubvh_codes(packed),
        "ids": [it.get("id") for it in batch],
    }
    return as_torch(out, to_torch)
