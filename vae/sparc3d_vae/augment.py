"""The 24 rotations of the cube, exact on the Sparcubes grid: training augmentation.

A rotation that maps the cube [0, N]³ onto itself permutes the axes and flips some of them, so a
grid vertex goes to a grid vertex and a cell to a cell: nothing is resampled. It is written as
`perm`, `flip` with new axis i = old axis perm[i], reversed when flip[i]:

- a vertex v ∈ [0, N] goes to v[perm[i]] (N − v[perm[i]] when flipped), a cell (its minimum
  corner c ∈ [0, N − 1]) to c[perm[i]] (N − 1 − c[perm[i]] when flipped);
- φ is a scalar and moves with its vertex: the 8 corner values of a cell are permuted as the
  corners are (`corner_source`);
- δ is a vector: its components are permuted as the axes and negated on flipped axes.

The 48 signed permutations are the symmetries of the cube; the 24 with determinant +1 are the
rotations (the others mirror the shape). `vae/tests/test_augment.py` checks the rotated
features against a dense grid rotated with numpy.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import List, Tuple

import numpy as np

from .data import Sample


@dataclass(frozen=True)
class Rotation:
    """new axis i = old axis perm[i], reversed when flip[i]."""

    perm: Tuple[int, int, int]
    flip: Tuple[bool, bool, bool]

    def matrix(self) -> np.ndarray:
        """The signed permutation matrix R (new = R · old about the cube's centre)."""
        m = np.zeros((3, 3), np.int64)
        for i, (p, f) in enumerate(zip(self.perm, self.flip)):
            m[i, p] = -1 if f else 1
        return m


def _rotations() -> List[Rotation]:
    out = []
    for perm in itertools.permutations(range(3)):
        for flip in itertools.product((False, True), repeat=3):
            r = Rotation(perm, flip)
            if round(np.linalg.det(r.matrix())) == 1:
                out.append(r)
    return out


#: The 24 rotations; index 0 is the identity.
ROTATIONS: List[Rotation] = _rotations()
#: 8 corners in the order of the shards and of `sparse.CHILD_OFFSETS` (o = 4·dx + 2·dy + dz).
_CORNERS = np.array([[(o >> 2) & 1, (o >> 1) & 1, o & 1] for o in range(8)], np.int64)


def corner_source(r: Rotation) -> np.ndarray:
    """For each corner k' of a rotated cell, the corner k of the original cell it comes from."""
    src = np.empty(8, np.int64)
    for k_new, o_new in enumerate(_CORNERS):
        o = np.empty(3, np.int64)
        for i, (p, f) in enumerate(zip(r.perm, r.flip)):
            o[p] = 1 - o_new[i] if f else o_new[i]
        src[k_new] = 4 * o[0] + 2 * o[1] + o[2]
    return src


def rotate_sample(s: Sample, r: Rotation) -> Sample:
    """The sample rotated by `r` on its grid (resolution from its meta): cells moved, corner
    features permuted, δ rotated. The identity returns the sample itself."""
    if r == ROTATIONS[0]:
        return s
    n = int(s.meta["resolution"])
    perm, flip = list(r.perm), np.array(r.flip)
    cells = s.cells[:, perm].astype(np.int64)
    cells = np.where(flip[None, :], n - 1 - cells, cells).astype(np.int32)
    src = corner_source(r)
    phi = s.feats[:, :8][:, src]
    parts = [phi]
    if s.feats.shape[1] > 8:
        delta = s.feats[:, 8:32].reshape(-1, 8, 3)[:, src][:, :, perm]
        delta = np.where(flip[None, None, :], -delta, delta)
        parts.append(delta.reshape(-1, 24))
    return Sample(s.id, s.meta, cells, np.concatenate(parts, axis=1).astype(np.float32))


def rotation_for(seed: int, step: int, position: int) -> Rotation:
    """The rotation of the item at `position` of a step's global batch: a pure function of
    (seed, step, position), so runs repeat and resume exactly, whatever the world size."""
    rng = np.random.default_rng([seed, step, position])
    return ROTATIONS[int(rng.integers(len(ROTATIONS)))]
