"""Which items a seeded sample takes: the same as `sparc3d validate` and `sparc3d eval --sample`,
so that `evaluate` measures, and `train.hold_out` leaves out, the items the binary would pick."""

from __future__ import annotations

import hashlib
import struct
from typing import Iterable, List


def sample_key(seed: int, item_id: str) -> int:
    """The sampling key `sparc3d validate` and `sparc3d eval --sample` use (pipeline/src/rows/sample.rs):
    the first 8 bytes, big-endian, of sha256(seed as 8 little-endian bytes ‖ id)."""
    d = hashlib.sha256(struct.pack("<Q", seed) + item_id.encode()).digest()
    return int.from_bytes(d[:8], "big")


def choose(ids: Iterable[str], k: int, seed: int) -> List[str]:
    """The k ids with the smallest (key, id): the same items as `sparc3d eval JOB --sample k`."""
    return [i for _, i in sorted((sample_key(seed, i), i) for i in ids)[:k]]
