"""The order a `StreamingDataset` yields its items in: a pure function of the seed, the epoch,
the rank and the DataLoader worker, so that every rank computes the same split without a word
to the others, and a resumed run replays its order and skips what it had yielded.

An epoch's order: the row groups ("blocks") of the job in an order shuffled by (seed, epoch),
their selected items in file order within each; that sequence is cut into one contiguous span
per rank, each rank's span into one per DataLoader worker (counts differ by at most one, or
none with `pad` / `drop_last`), and each worker yields its span through a shuffle buffer of
`buffer_size` items, its picks drawn from (seed, epoch, rank, worker). Contiguous spans keep
each worker reading whole row groups in order, as the plain reader does.

Randomness comes from `random.Random(int).random()`, whose sequence Python guarantees not to
change across versions (the `random` module's documentation, "Notes on Reproducibility"); the
shuffles are written here on top of it rather than `random.shuffle` or numpy's generators,
whose algorithms may change.
"""

from __future__ import annotations

import hashlib
import random
from typing import List, Sequence, Tuple

import numpy as np


def derived_seed(*parts: object) -> int:
    """A 64-bit seed from the parts (their text), the same on every machine and Python."""
    text = ":".join(str(p) for p in ("sparc3d-stream",) + parts)
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "little")


def shuffled(n: int, rng: random.Random) -> List[int]:
    """0..n-1 in a Fisher-Yates order drawn from `rng.random()`."""
    out = list(range(n))
    for i in range(n - 1, 0, -1):
        j = int(rng.random() * (i + 1))
        out[i], out[j] = out[j], out[i]
    return out


def epoch_order(block_sizes: Sequence[int], seed: int, epoch: int, shuffle: bool) -> np.ndarray:
    """Every item number (0..N-1, numbered block after block) in the epoch's block order."""
    sizes = np.asarray(block_sizes, dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes)])
    blocks = (shuffled(len(sizes), random.Random(derived_seed("blocks", seed, epoch)))
              if shuffle else range(len(sizes)))
    parts = [np.arange(starts[b], starts[b + 1]) for b in blocks]
    return np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)


def span(n: int, part: int, parts: int) -> Tuple[int, int]:
    """The `part`-th of `parts` contiguous spans of 0..n-1, sizes differing by at most one."""
    return n * part // parts, n * (part + 1) // parts


def rank_items(order: np.ndarray, rank: int, world_size: int, pad: bool,
               drop_last: bool) -> np.ndarray:
    """The rank's span of the epoch's order. With `pad`, the order is first lengthened to a
    multiple of `world_size` by repeating its start (every rank gets ceil(N / world_size)
    items, a few of them twice in the epoch); with `drop_last`, cut to one (floor(N /
    world_size) each, the last N mod world_size items of this epoch's order left out);
    otherwise every item is one rank's, ranks' counts differing by at most one."""
    n = len(order)
    if pad and n:
        order = np.resize(order, -(-n // world_size) * world_size)
    elif drop_last:
        order = order[: n // world_size * world_size]
    lo, hi = span(len(order), rank, world_size)
    return order[lo:hi]


def buffer_order(n: int, buffer_size: int, rng: random.Random) -> np.ndarray:
    """The order a shuffle buffer of `buffer_size` yields positions 0..n-1 read in order:
    once it is full, each position read displaces one drawn at random, which is yielded; at
    the end the rest come out in a shuffled order. At most `buffer_size` positions are read
    and not yet yielded at any time."""
    buf: List[int] = []
    out: List[int] = []
    for p in range(n):
        if len(buf) < buffer_size:
            buf.append(p)
            continue
        j = int(rng.random() * buffer_size)
        out.append(buf[j])
        buf[j] = p
    out += [buf[i] for i in shuffled(len(buf), rng)]
    return np.asarray(out, dtype=np.int64)


def worker_order(n: int, shuffle: bool, buffer_size: int, seed: int, epoch: int, rank: int,
                 worker: int) -> np.ndarray:
    """The order a worker yields the n positions of its span in (read order when not
    shuffled)."""
    if not shuffle:
        return np.arange(n, dtype=np.int64)
    rng = random.Random(derived_seed("buffer", seed, epoch, rank, worker))
    return buffer_order(n, buffer_size, rng)
