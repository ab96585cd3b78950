"""Batches of items: the sparse layout sparse-convolution libraries expect (`collate_sparse`)
and the stacked samples of vector-set VAEs (`collate_vecset`)."""

from __future__ import annotations

from typing import Any, Dict, Optional, Sequence

import numpy as np

from .schema import OPTIONAL_SAMPLE_TENSORS

#: The 8 corners of a cell as offsets from its minimum corner; corner `o` is
#: `(o >> 2 & 1, o >> 1 & 1, o & 1)`, the order of `corner_index` and of `collate_sparse`'s
#: `corners`.
CORNER_OFFSETS = np.array([[(o >> 2) & 1, (o >> 1) & 1, o & 1] for o in range(8)], dtype=np.int64)


def as_torch(out: Dict[str, Any], to_torch: bool) -> Dict[str, Any]:
    """`out` with its numpy arrays as torch tensors when `to_torch` (lists stay lists)."""
    if to_torch:
        import torch

        for k, v in out.items():
            if isinstance(v, np.ndarray):
                out[k] = torch.from_numpy(v)
    return out


def _vertex_keys(xyz: np.ndarray) -> np.ndarray:
    """One int64 per grid point (x, y, z in 0..=4096), ordered as (x, y, z) lexicographically."""
    xyz = xyz.astype(np.int64)
    return (xyz[..., 0] << 26) | (xyz[..., 1] << 13) | xyz[..., 2]


def corner_index(coords: np.ndarray, cells: np.ndarray, item_id: Optional[str] = None) -> np.ndarray:
    """Rows of `coords` ([K, 3], sorted as the shards store them) holding the 8 corners of each
    cell of `cells` ([C, 3] minimum corners): int64 [C, 8] in `CORNER_OFFSETS` order. A ValueError
    names the item when a corner is missing (the shard contract says there is none)."""
    keys = _vertex_keys(np.asarray(coords))
    if len(keys) > 1 and not np.all(keys[1:] > keys[:-1]):
        raise ValueError(f"item {item_id!r}: coords are not sorted and unique (docs/FORMAT.md)")
    want = _vertex_keys(np.asarray(cells)[:, None, :] + CORNER_OFFSETS[None, :, :])
    idx = np.searchsorted(keys, want)
    found = idx < len(keys)
    found[found] = keys[idx[found]] == want[found]
    if not found.all():
        c = int(np.argwhere(~found.all(axis=1))[0, 0])
        raise ValueError(f"item {item_id!r}: cell {np.asarray(cells)[c].tolist()} has a corner "
                         "that is not among the active vertices (docs/FORMAT.md)")
    return idx.astype(np.int64)


def collate_sparse(batch: Sequence[Dict[str, Any]], to_torch: bool = False) -> Dict[str, Any]:
    """Concatenates items into the layout sparse-convolution libraries expect:

    - `coords` int32 [ΣK, 4]: batch index, x, y, z
    - `feats` float32 [ΣK, 4]: sdf, deformation x, y, z
    - `offsets` int64 [B + 1]: item b's rows are `offsets[b]:offsets[b + 1]`
    - `cells` int32 [ΣC, 4] (batch index + minimum corner) and `cell_offsets` int64 [B + 1]
    - `corners` int64 [ΣC, 8]: the rows of `coords` / `feats` holding each cell's 8 corners,
      in `CORNER_OFFSETS` order (so `feats[corners, 0]` is φ at the corners, [ΣC, 8])
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
    corners = np.zeros((sum(cs), 8), dtype=np.int64)
    for b, it in enumerate(batch):
        lo, hi = offsets[b], offsets[b + 1]
        coords[lo:hi, 0] = b
        coords[lo:hi, 1:] = it["coords"]
        feats[lo:hi, 0] = it["sdf"]
        feats[lo:hi, 1:] = it["deformation"]
        clo, chi = cell_offsets[b], cell_offsets[b + 1]
        cells[clo:chi, 0] = b
        cells[clo:chi, 1:] = it["cells"]
        corners[clo:chi] = corner_index(it["coords"], it["cells"], it.get("id")) + lo
    out: Dict[str, Any] = {
        "coords": coords,
        "feats": feats,
        "offsets": offsets,
        "cells": cells,
        "cell_offsets": cell_offsets,
        "corners": corners,
        "ids": [it["id"] for it in batch],
        "resolution": [it["resolution"] for it in batch],
    }
    return as_torch(out, to_torch)


def _samples_of(item: Dict[str, Any]) -> Dict[str, Any]:
    """An item's samples: its `samples`, or the item itself (an `iter_export` vecset-npz dict)."""
    return item["samples"] if "samples" in item else item


def collate_vecset(batch: Sequence[Dict[str, Any]], to_torch: bool = False) -> Dict[str, Any]:
    """Stacks the samples of items (dicts with `samples`, or the dicts `iter_export` yields for
    `vecset-npz`) into float32 arrays [B, n, ...]: `surface` [B, n, 6] (points + normals, as
    Hunyuan3D-2.1 and Dora feed their encoders), `sharp_surface` [B, m, 6], `near_points`
    [B, q, 3], `near_sdf` [B, q], `volume_points` [B, p, 3], `volume_sdf` [B, p],
    `volume_occupancy` [B, p], and where every item has them `sharp_near_points` [B, r, 3] and
    `sharp_near_sdf` [B, r]. Every item must have the same counts (a job's config fixes
    them; the sharp kinds are empty for a mesh without sharp edges, so they are stacked only
    when all items have the same number, else given as lists)."""
    def get(it, name):
        return np.asarray(_samples_of(it)[name])

    out: Dict[str, Any] = {}
    out["surface"] = np.stack([np.concatenate([get(it, "surface_points"), get(it, "surface_normals")], 1)
                               for it in batch]).astype(np.float32)
    sharp = [np.concatenate([get(it, "sharp_points"), get(it, "sharp_normals")], 1) for it in batch]
    if len({len(x) for x in sharp}) == 1:
        out["sharp_surface"] = np.stack(sharp).astype(np.float32)
    else:
        out["sharp_surface"] = [x.astype(np.float32) for x in sharp]
    for name in ("near_points", "near_sdf", "volume_points", "volume_sdf", "volume_occupancy"):
        out[name] = np.stack([get(it, name) for it in batch]).astype(np.float32)
    for name in OPTIONAL_SAMPLE_TENSORS:
        if all(name in _samples_of(it) for it in batch):
            parts = [get(it, name).astype(np.float32) for it in batch]
            same = len({len(x) for x in parts}) == 1
            out[name] = np.stack(parts) if same else parts
    out["ids"] = [it.get("id") for it in batch]
    return as_torch(out, to_torch)
