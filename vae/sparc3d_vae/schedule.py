"""What each training step takes: the items of its global batch (a pure function of seed and
step, so a resumed run sees the same batches), its learning rate, and the batch cut into parts
that fit the cell budget."""

from __future__ import annotations

import functools
import math
from typing import List, Tuple

import torch

from .config import Config


@functools.lru_cache(maxsize=4)
def _epoch_order(seed: int, epoch: int, n: int) -> Tuple[int, ...]:
    g = torch.Generator().manual_seed(seed * 1_000_003 + epoch)
    return tuple(torch.randperm(n, generator=g).tolist())


def batch_indices(step: int, n: int, batch_size: int, seed: int) -> List[int]:
    """Items of a step's global batch. The items form an endless stream, one permutation per
    epoch seeded by (seed, epoch); step s takes positions s·B .. s·B + B − 1 of it, so every
    batch is full (an epoch's tail continues into the next one) and can be cut into equal
    shares for the ranks."""
    out: List[int] = []
    pos = step * batch_size
    while len(out) < batch_size:
        epoch, j = divmod(pos, n)
        take = min(batch_size - len(out), n - j)
        out += _epoch_order(seed, epoch, n)[j:j + take]
        pos += take
    return out


def learning_rate(step: int, cfg: Config) -> float:
    """Linear warm-up, then a cosine from `lr` down to `final_lr_fraction · lr` at the last step."""
    t = cfg.train
    if step < t.warmup_steps:
        return t.lr * (step + 1) / t.warmup_steps
    span = max(1, t.steps - t.warmup_steps)
    x = min(1.0, (step - t.warmup_steps) / span)
    low = t.lr * t.final_lr_fraction
    return low + (t.lr - low) * 0.5 * (1.0 + math.cos(math.pi * x))


def split_parts(samples, limit: int) -> List[List[int]]:
    """Positions of a batch grouped into parts of at most `limit` cells each (in order)."""
    parts: List[List[int]] = []
    cells = 0
    for i, s in enumerate(samples):
        n = len(s.cells)
        if parts and cells + n <= limit:
            parts[-1].append(i)
            cells += n
        else:
            parts.append([i])
            cells = n
    return parts
