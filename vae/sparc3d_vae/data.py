"""From shards to batches and back: items read with `sparc3d_reader`, per-cell corner features
(φ at the 8 corners, then δ at the 8 corners), batches as sparse tensors, and the decoder's
per-corner predictions written back as sparse cubes (averaged over the cells sharing a corner).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Sequence

import numpy as np
import pyarrow as pa
import torch

import sparc3d_reader as reader

from .sparse import CHILD_OFFSETS, SparseTensor, hash_coords, unhash


class DataError(ValueError):
    """Input data that cannot be used; the message names the job, shard or item."""


@dataclass
class JobInfo:
    """What the VAE needs to know about the jobs it reads."""

    shards: List[str]
    deformation: bool
    resolutions: List[int]


def job_info(paths: Sequence[str]) -> JobInfo:
    """Shards of the given jobs (or shard files), checked for the schema version, and whether
    they hold a deformation (the job's `params.deform`). Jobs that disagree are refused."""
    try:
        shards = reader.shard_paths(list(paths))
    except FileNotFoundError as e:
        raise DataError(str(e)) from None
    if not shards:
        raise DataError(f"{', '.join(map(str, paths))}: no complete shards (run `sparc3d run` first)")
    deform = set()
    resolutions = set()
    for s in shards:
        try:
            reader.check_schema_version(s)
        except ValueError as e:
            raise DataError(str(e)) from None
        params = reader.shard_config(s).get("params", {})
        deform.add(bool(params.get("deform", True)))
        if "resolution" in params:
            resolutions.add(int(params["resolution"]))
    if len(deform) > 1:
        raise DataError("the jobs disagree on params.deform (some store a deformation, some "
                        "do not); train on jobs of one kind")
    return JobInfo([str(s) for s in shards], deform.pop(), sorted(resolutions))


@dataclass
class Sample:
    """One item as the VAE reads it: its cells and their features."""

    id: str
    meta: Dict[str, Any]  # resolution, center, scale, uri, item_index
    cells: np.ndarray     # int32 [C, 3]
    feats: np.ndarray     # float32 [C, 8] or [C, 32]: φ at the corners, then δ [8 × 3]


def to_sample(item: Dict[str, Any], deformation: bool) -> Sample:
    """Corner features of an item (a `sparc3d_reader` item). An item with no active cells is
    refused, naming it."""
    if len(item["cells"]) == 0:
        raise DataError(f"item {item['id']!r} ({item.get('uri')}): no active cells")
    corners = reader.corner_index(item["coords"], item["cells"], item["id"])
    phi = item["sdf"][corners]  # [C, 8]
    feats = [phi]
    if deformation:
        feats.append(item["deformation"][corners].reshape(len(corners), 24))
    meta = {k: item[k] for k in ("resolution", "center", "scale", "uri", "item_index")}
    return Sample(item["id"], meta, item["cells"].astype(np.int32),
                  np.concatenate(feats, axis=1).astype(np.float32))


def sample_cells(s: Sample) -> int:
    """Cells of a sample (what memory grows with)."""
    return len(s.cells)


def make_batch(samples: Sequence[Sample], device: torch.device) -> SparseTensor:
    """The samples as one sparse tensor at full resolution: coords (b, x, y, z) of the cells,
    features = the corner features (which are also the targets)."""
    coords = np.concatenate([np.concatenate([np.full((len(s.cells), 1), b, np.int32), s.cells], 1)
                             for b, s in enumerate(samples)])
    feats = np.concatenate([s.feats for s in samples])
    return SparseTensor.build(torch.from_numpy(coords).to(device), torch.from_numpy(feats).to(device),
                              level=0, batch_size=len(samples))


class Samples:
    """Indexable samples of jobs, decoded on demand (and kept when `cache` is on)."""

    def __init__(self, info: JobInfo, cache: bool = True):
        self.info = info
        self.ds = reader.SparseCubesDataset(info.shards)
        self.cache: Optional[Dict[int, Sample]] = {} if cache else None

    def __len__(self) -> int:
        return len(self.ds)

    @property
    def ids(self) -> List[str]:
        """Item ids in order."""
        return list(self.ds.ids)

    def __getitem__(self, i: int) -> Sample:
        if self.cache is not None and i in self.cache:
            return self.cache[i]
        s = to_sample(self.ds[i], self.info.deformation)
        if self.cache is not None:
            self.cache[i] = s
        return s

    def index_of(self, item_id: str) -> int:
        """Position of the item with this id; a DataError naming the id when absent."""
        try:
            return self.ds.ids.index(item_id)
        except ValueError:
            raise DataError(f"no ok item with id {item_id!r} in {', '.join(self.info.shards)}") from None


# --- Decoded cells back to sparse cubes ---------------------------------------------------------

#: Smallest magnitude written for an inside corner, so that it stays strictly negative
#: (φ = 0 counts as outside, docs/ALGORITHM.md §6).
MIN_INSIDE = 1e-4
#: Deformation is clamped as Sparcubes clamps it (docs/ALGORITHM.md §5).
MAX_DELTA = 0.45


@dataclass
class Cubes:
    """Sparse cubes of one item, as the shards store them (docs/FORMAT.md)."""

    coords: np.ndarray       # uint16 [K, 3], sorted
    sdf: np.ndarray          # float32 [K]
    deformation: np.ndarray  # float32 [K, 3]
    cells: np.ndarray        # uint16 [C, 3], sorted, each with a sign change


def corners_to_cubes(cells: SparseTensor, sign_logits: torch.Tensor, magnitude: torch.Tensor,
                     delta: Optional[torch.Tensor]) -> List[Cubes]:
    """Per-cell, per-corner predictions → per-item sparse cubes. Each grid vertex takes the mean
    sign logit, magnitude and δ of the cells sharing it; φ = −|φ| where the mean logit says
    inside. Only cells with a sign change among their corners are kept (the others hold no
    surface), and only their corners."""
    dev = cells.coords.device
    c = cells.coords.to(torch.int64)
    offs = torch.tensor(CHILD_OFFSETS, dtype=torch.int64, device=dev)
    corner = torch.cat([c[:, None, :1].expand(-1, 8, 1), c[:, None, 1:] + offs[None]], dim=2).view(-1, 4)
    vkeys, inverse = torch.unique(hash_coords(corner), sorted=True, return_inverse=True)
    n = len(vkeys)
    count = torch.zeros(n, device=dev).index_add(0, inverse, torch.ones(len(inverse), device=dev))
    logit = torch.zeros(n, device=dev).index_add(0, inverse, sign_logits.reshape(-1).float()) / count
    mag = torch.zeros(n, device=dev).index_add(0, inverse, magnitude.reshape(-1).float()) / count
    inside = logit > 0
    phi = torch.where(inside, -mag.clamp_min(MIN_INSIDE), mag)
    if delta is not None:
        d = torch.zeros(n, 3, device=dev).index_add(0, inverse, delta.reshape(-1, 3).float()) / count[:, None]
        d = d.clamp(-MAX_DELTA, MAX_DELTA)
    else:
        d = torch.zeros(n, 3, device=dev)
    cell_inside = inside[inverse].view(-1, 8)
    keep = cell_inside.any(dim=1) & ~cell_inside.all(dim=1)
    used = torch.zeros(n, dtype=torch.bool, device=dev)
    used[inverse.view(-1, 8)[keep].reshape(-1)] = True
    vcoords = unhash(vkeys)
    out = []
    for b in range(cells.batch_size):
        vm = used & (vcoords[:, 0] == b)
        cm = keep & (cells.coords[:, 0] == b)
        out.append(Cubes(
            coords=vcoords[vm, 1:].cpu().numpy().astype(np.uint16),
            sdf=phi[vm].cpu().numpy().astype(np.float32),
            deformation=d[vm].cpu().numpy().astype(np.float32),
            cells=cells.coords[cm, 1:].cpu().numpy().astype(np.uint16)))
    return out


def cubes_row(item_id: str, meta: Dict[str, Any], cubes: Cubes) -> Dict[str, Any]:
    """A row of a tensor file for `sparc3d extract` (docs/FORMAT.md, "Tensor files")."""
    center = [float(v) for v in meta["center"]]
    return {"id": item_id, "resolution": int(meta["resolution"]),
            "center_x": center[0], "center_y": center[1], "center_z": center[2],
            "scale": float(meta["scale"]),
            "coords": cubes.coords, "sdf": cubes.sdf, "deformation": cubes.deformation,
            "cells": cubes.cells}


#: Column types of a tensor file's plain columns (those of a shard, docs/FORMAT.md).
CUBES_SCHEMA = {"id": pa.string(), "resolution": pa.uint32(), "center_x": pa.float64(),
                "center_y": pa.float64(), "center_z": pa.float64(), "scale": pa.float64()}
CUBES_TENSORS = ("coords", "sdf", "deformation", "cells")


def write_cubes(path, rows: Sequence[Dict[str, Any]]) -> None:
    """Writes rows of `cubes_row` as a tensor file `sparc3d extract` reads."""
    reader.write_tensor_file(path, rows, CUBES_TENSORS, {"sparc3d.kind": "cubes"}, CUBES_SCHEMA)
