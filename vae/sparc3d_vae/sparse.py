"""Sparse voxel tensors in plain PyTorch: coordinates hashed to int64 keys, kernel maps found by
sort + searchsorted.

A `SparseTensor` holds `coords` int32 [N, 4] as (batch, x, y, z), the layout of TRELLIS' sparse
tensors and of spconv / torchsparse, and `feats` [N, C]. Rows are kept sorted by their key, so
a lookup is one `searchsorted` into the tensor's own keys. `level` says how coarse the grid is:
at level l a voxel covers 2^l cells of the full-resolution grid and its coordinates are the
full-resolution ones shifted right by l.

Kernel maps (which input row feeds which output row through which kernel offset) depend only on
the coordinates, so tensors that share coordinates share one `cache` dict and every map is
built once per batch.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import torch

#: Bits per spatial coordinate in a key. Coordinates are stored shifted by one (so a neighbour at
#: -1 still has a key), which leaves room for grid coordinates 0..16381.
COORD_BITS = 14
_SPAN = 1 << COORD_BITS
#: Largest grid coordinate a key can hold (a 4096³ grid uses 0..4096).
MAX_COORD = _SPAN - 3


def hash_coords(coords: torch.Tensor) -> torch.Tensor:
    """int64 keys of (batch, x, y, z) rows, increasing in (batch, x, y, z) lexicographic order.

    Layout: batch in the high bits, then x + 1, y + 1, z + 1 in `COORD_BITS` bits each, so the
    key of a neighbour is the key plus a constant (`offset_key`) and keys never collide."""
    c = coords.to(torch.int64)
    return (((c[:, 0] * _SPAN + c[:, 1] + 1) * _SPAN + c[:, 2] + 1) * _SPAN) + c[:, 3] + 1


def offset_key(dx: int, dy: int, dz: int) -> int:
    """What a spatial offset adds to a key (see `hash_coords`)."""
    return (dx * _SPAN + dy) * _SPAN + dz


def unhash(keys: torch.Tensor) -> torch.Tensor:
    """The inverse of `hash_coords`: int32 [N, 4] coordinates."""
    z = keys % _SPAN - 1
    rest = keys // _SPAN
    y = rest % _SPAN - 1
    rest = rest // _SPAN
    x = rest % _SPAN - 1
    b = rest // _SPAN
    return torch.stack([b, x, y, z], dim=1).to(torch.int32)


def lookup(keys: torch.Tensor, query: torch.Tensor) -> Tuple[torch.Tensor, torch.Tensor]:
    """Rows of sorted `keys` equal to each `query` key: (index, found); index is only
    meaningful where found."""
    idx = torch.searchsorted(keys, query)
    idx = idx.clamp_max(max(len(keys) - 1, 0))
    found = keys[idx] == query if len(keys) else torch.zeros_like(query, dtype=torch.bool)
    return idx, found


#: Offsets of a 3×3×3 kernel in the order of a dense `conv3d` weight's last three dims
#: (kernel index k = 9·(dx+1) + 3·(dy+1) + (dz+1)).
SUBM_OFFSETS: List[Tuple[int, int, int]] = [
    (dx, dy, dz) for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1)]
#: Index of the centre offset in `SUBM_OFFSETS`.
CENTRE = 13
#: The 8 children of a voxel, in the order of a dense 2×2×2 kernel (o = 4·dx + 2·dy + dz).
CHILD_OFFSETS: List[Tuple[int, int, int]] = [
    (dx, dy, dz) for dx in (0, 1) for dy in (0, 1) for dz in (0, 1)]


@dataclass
class SparseTensor:
    """Sparse voxels of a batch: coords int32 [N, 4] (batch, x, y, z) sorted by key, feats
    [N, C], the grid level, the batch size, and a cache of kernel maps shared by every tensor
    with the same coordinates."""

    coords: torch.Tensor
    feats: torch.Tensor
    level: int = 0
    batch_size: int = 1
    cache: Dict[str, object] = field(default_factory=dict)

    @staticmethod
    def build(coords: torch.Tensor, feats: torch.Tensor, level: int = 0,
              batch_size: Optional[int] = None) -> "SparseTensor":
        """A tensor from rows in any order: sorts them by key; refuses duplicates and
        coordinates outside the key's range."""
        if coords.ndim != 2 or coords.shape[1] != 4:
            raise ValueError(f"coords must be [N, 4] (batch, x, y, z), got {list(coords.shape)}")
        if len(coords) != len(feats):
            raise ValueError(f"{len(coords)} coords but {len(feats)} feature rows")
        if len(coords):
            lo, hi = int(coords[:, 1:].min()), int(coords[:, 1:].max())
            if lo < 0 or hi > MAX_COORD:
                raise ValueError(f"coordinates {lo}..{hi} outside 0..{MAX_COORD}")
        keys = hash_coords(coords)
        keys, order = torch.sort(keys)
        if len(keys) > 1 and bool((keys[1:] == keys[:-1]).any()):
            raise ValueError("duplicate coordinates in a sparse tensor")
        bs = batch_size if batch_size is not None else (int(coords[:, 0].max()) + 1 if len(coords) else 0)
        t = SparseTensor(coords[order].to(torch.int32), feats[order], level, bs)
        t.cache["keys"] = keys
        return t

    @property
    def keys(self) -> torch.Tensor:
        """Sorted int64 keys of the rows (cached)."""
        k = self.cache.get("keys")
        if k is None:
            k = hash_coords(self.coords)
            self.cache["keys"] = k
        return k  # type: ignore[return-value]

    def replace(self, feats: torch.Tensor) -> "SparseTensor":
        """The same voxels (and cache) with other features."""
        return SparseTensor(self.coords, feats, self.level, self.batch_size, self.cache)

    def neighbours(self) -> torch.Tensor:
        """Kernel map of a submanifold 3×3×3 convolution (outputs = inputs) as a table: int64
        [N, 27], entry (r, k) is the row at offset `SUBM_OFFSETS[k]` from row r, or N (a
        padding row) where that voxel is not active. Built by searchsorted into the sorted
        keys; cached."""
        nb = self.cache.get("neighbours")
        if nb is None:
            keys = self.keys
            deltas = torch.tensor([offset_key(*o) for o in SUBM_OFFSETS], dtype=torch.int64,
                                  device=keys.device)
            idx, found = lookup(keys, keys[:, None] + deltas[None, :])
            nb = torch.where(found, idx, torch.full_like(idx, len(keys)))
            self.cache["neighbours"] = nb
        return nb  # type: ignore[return-value]

    def batch_rows(self) -> List[torch.Tensor]:
        """Row ranges per batch item as index tensors (rows are sorted by batch first)."""
        counts = torch.bincount(self.coords[:, 0].to(torch.int64), minlength=self.batch_size)
        ends = torch.cumsum(counts, 0).tolist()
        starts = [0] + ends[:-1]
        return [torch.arange(s, e, device=self.coords.device) for s, e in zip(starts, ends)]


def parent_structure(child: SparseTensor) -> Tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The voxels one level up of `child`'s voxels: (parent coords sorted by key, the parent
    row of every child row, the child offset index 0..7 of every child row). Cached on the
    child's cache, so the decoder of the same batch reuses the encoder's structure."""
    got = child.cache.get("parent")
    if got is None:
        c = child.coords.to(torch.int64)
        parent = torch.cat([c[:, :1], c[:, 1:] >> 1], dim=1)
        pkeys = hash_coords(parent)
        ukeys, inverse = torch.unique(pkeys, sorted=True, return_inverse=True)
        o = c[:, 1:] & 1
        offset = o[:, 0] * 4 + o[:, 1] * 2 + o[:, 2]
        got = (unhash(ukeys), inverse, offset)
        child.cache["parent"] = got
        child.cache["parent_keys"] = ukeys
    return got  # type: ignore[return-value]


def children_of(parent: SparseTensor, child_coords: torch.Tensor) -> Tuple[torch.Tensor, torch.Tensor]:
    """For child voxels (int32 [M, 4], one level down), the parent row of each and its child
    offset index 0..7. Every child's parent must be in `parent`."""
    c = child_coords.to(torch.int64)
    pk = hash_coords(torch.cat([c[:, :1], c[:, 1:] >> 1], dim=1))
    idx, found = lookup(parent.keys, pk)
    if not bool(found.all()):
        raise ValueError("a child voxel has no parent among the coarser voxels")
    o = c[:, 1:] & 1
    return idx, o[:, 0] * 4 + o[:, 1] * 2 + o[:, 2]


def expand_children(parent: SparseTensor, mask: torch.Tensor) -> torch.Tensor:
    """Coordinates (sorted by key) of the children selected by `mask` [N, 8] (bool, in
    `CHILD_OFFSETS` order) of the parent voxels, one level down."""
    offs = torch.tensor(CHILD_OFFSETS, dtype=torch.int64, device=parent.coords.device)
    rows, o = torch.nonzero(mask, as_tuple=True)
    p = parent.coords[rows].to(torch.int64)
    child = torch.cat([p[:, :1], (p[:, 1:] << 1) + offs[o]], dim=1)
    keys, _ = torch.sort(hash_coords(child))
    return unhash(keys)
