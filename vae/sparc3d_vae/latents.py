"""Latents on disk: `encode` writes them, `read_latents` reads them back for `decode`.

Latents are Parquet shards `LATENTS/part-NNNNN.parquet` (with a `part-NNNNN.complete.json`),
one row per item: `id`, `item_index`, `uri`, `resolution`, `center_x/y/z`, `scale`,
`downsample`, and the tensors `coords` (int32 [n, 3], latent grid), `mean` and `logvar`
(float32 [n, C]) in the shards' tensor encoding, so `sparc3d_reader.iter_tensor_rows` reads
them.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import numpy as np
import pyarrow as pa

import sparc3d_reader as reader

from .data import Sample
from .loaded import Loaded
from .runtime import UsageError

#: The tensor columns of a latent shard.
LATENT_TENSORS = ("coords", "mean", "logvar")
#: The plain columns of a latent shard and their Arrow types.
LATENT_SCHEMA = {"id": pa.string(), "item_index": pa.uint64(), "uri": pa.string(),
                 "resolution": pa.uint32(), "center_x": pa.float64(), "center_y": pa.float64(),
                 "center_z": pa.float64(), "scale": pa.float64(), "downsample": pa.uint32()}
#: Items per latent shard.
LATENT_SHARD_SIZE = 256


def _latent_row(s: Sample, lat: Dict[str, np.ndarray], downsample: int) -> Dict[str, Any]:
    c = [float(v) for v in s.meta["center"]]
    return {"id": s.id, "item_index": int(s.meta["item_index"]), "uri": s.meta["uri"],
            "resolution": int(s.meta["resolution"]), "center_x": c[0], "center_y": c[1],
            "center_z": c[2], "scale": float(s.meta["scale"]), "downsample": downsample, **lat}


def encode(ckpt: Path, data: Sequence[str], out: Path, device: str,
           max_cells: Optional[int] = None) -> Dict[str, Any]:
    """Writes the latents of every ok item of the jobs to `out` as Parquet shards."""
    loaded = Loaded(ckpt, device, max_cells)
    samples = loaded.load_samples(data)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    meta = {"sparc3d.kind": "latents", "sparc3d_vae.checkpoint": loaded.digest,
            "sparc3d_vae.config": json.dumps(loaded.cfg.to_dict(), sort_keys=True)}
    rows: List[Dict[str, Any]] = []
    shard = 0
    voxels: List[int] = []

    def flush() -> None:
        nonlocal rows, shard
        path = out / f"part-{shard:05d}.parquet"
        reader.write_tensor_file(path, rows, LATENT_TENSORS, meta, LATENT_SCHEMA)
        reader.write_completion_record(
            path, {"shard": shard, "rows": len(rows), "checkpoint": loaded.digest})
        rows, shard = [], shard + 1

    items = (samples[i] for i in range(len(samples)))
    for group in loaded.batches(items):
        for s, lat in zip(group, loaded.encode(group)):
            rows.append(_latent_row(s, lat, loaded.cfg.model.downsample))
            voxels.append(len(lat["coords"]))
            if len(rows) == LATENT_SHARD_SIZE:
                flush()
    if rows:
        flush()
    return {"items": len(voxels), "shards": shard,
            "latent_voxels_mean": float(np.mean(voxels)) if voxels else 0.0,
            "latent_channels": loaded.cfg.model.latent_channels}


def read_latents(latents: Path, ids: Optional[List[str]], loaded: Loaded) -> List[Dict[str, Any]]:
    """The latent rows of `ids` (in that order; None: every row) from the shards under
    `latents`, each checked to fit the checkpoint's latent channels and downsampling."""
    try:
        rows = list(reader.iter_tensor_rows(latents, LATENT_TENSORS))
    except (FileNotFoundError, ValueError) as e:
        raise UsageError(str(e)) from None
    if ids is not None:
        by_id = {r["id"]: r for r in rows}
        missing = [i for i in ids if i not in by_id]
        if missing:
            raise UsageError(f"{latents}: no latents for id {missing[0]!r}")
        rows = [by_id[i] for i in ids]
    _check_latents(rows, loaded, str(latents))
    return rows


def _check_latents(rows: List[Dict[str, Any]], loaded: Loaded, source: str) -> None:
    c = loaded.cfg.model
    for r in rows:
        if r["mean"] is None or r["mean"].ndim != 2 or r["mean"].shape[1] != c.latent_channels:
            shape = None if r["mean"] is None else list(r["mean"].shape)
            raise UsageError(f"{source}: item {r['id']!r} has latents of shape {shape}, the "
                             f"checkpoint expects [n, {c.latent_channels}]")
        if int(r.get("downsample") or 0) != c.downsample:
            raise UsageError(f"{source}: item {r['id']!r} was encoded with downsample "
                             f"{r.get('downsample')}, the checkpoint uses {c.downsample}")
