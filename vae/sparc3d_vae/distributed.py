"""Training on several processes: `torchrun --nproc_per_node N -m sparc3d_vae train ...`.

torchrun (`torch.distributed.run`) starts N copies of the command and tells each its place in
the environment variables `RANK`, `LOCAL_RANK` and `WORLD_SIZE` (and where to meet,
`MASTER_ADDR` / `MASTER_PORT`); a plain `sparc3d-vae train` has none of them and is a world of
one. Each process holds the whole model wrapped in `DistributedDataParallel`, which averages
the gradients over the processes during the backward pass, so every process takes the same
optimizer step and the weights stay identical (a digest of each rank's weights is compared at
every checkpoint). Processes meet over gloo on CPU and NCCL on CUDA, one GPU per process
(`LOCAL_RANK`).

The global batch (`train.batch_size` items) is a pure function of (seed, step); rank r trains
on its items r, r + N, r + 2N, ..., so `train.batch_size` must be a multiple of N. A run is
deterministic for a seed and a world size on CPU; a different world size gives another (equally
valid) run, and resuming a checkpoint with another world size is refused.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from typing import Dict, List

import torch
import torch.distributed as dist


@dataclass(frozen=True)
class World:
    """This process's place among the training processes."""

    rank: int = 0
    local_rank: int = 0
    size: int = 1

    @property
    def distributed(self) -> bool:
        return self.size > 1

    @property
    def main(self) -> bool:
        """Rank 0 writes the checkpoint, the log and the progress line."""
        return self.rank == 0


def world_from_env(env: Dict[str, str] = None) -> World:
    """The world torchrun describes in the environment (a world of one without it)."""
    env = os.environ if env is None else env

    def number(key: str, default: int) -> int:
        value = env.get(key)
        if value is None or value == "":
            return default
        try:
            return int(value)
        except ValueError:
            raise ValueError(f"{key}={value!r} in the environment is not an integer") from None

    size = number("WORLD_SIZE", 1)
    rank = number("RANK", 0)
    if size < 1 or not 0 <= rank < size:
        raise ValueError(f"RANK={rank}, WORLD_SIZE={size} in the environment: expected "
                         "0 ≤ RANK < WORLD_SIZE")
    return World(rank, number("LOCAL_RANK", rank), size)


def init(world: World, device: torch.device) -> None:
    """Joins the process group (gloo on CPU, NCCL on CUDA); nothing for a world of one."""
    if world.distributed and not dist.is_initialized():
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo",
                                rank=world.rank, world_size=world.size)


def shutdown(world: World) -> None:
    """Leaves the process group."""
    if world.distributed and dist.is_initialized():
        dist.destroy_process_group()


def shard(items: List[int], world: World) -> List[int]:
    """This rank's part of a global batch: every `world.size`-th item from position `rank`."""
    return items[world.rank::world.size]


def all_sum(values: torch.Tensor, world: World) -> torch.Tensor:
    """Sum over the ranks (the tensor itself for a world of one)."""
    if world.distributed:
        values = values.clone()
        dist.all_reduce(values, op=dist.ReduceOp.SUM)
    return values


def barrier(world: World) -> None:
    """Waits until every rank is here (nothing for a world of one)."""
    if world.distributed:
        dist.barrier()


def weights_digest(state: Dict[str, torch.Tensor]) -> str:
    """A digest of a state dict's tensors (names, shapes and bytes), to compare ranks."""
    h = hashlib.sha256()
    for name in sorted(state):
        t = state[name].detach().to("cpu").contiguous()
        h.update(name.encode())
        h.update(str(tuple(t.shape)).encode())
        h.update(t.reshape(-1).view(torch.uint8).numpy().tobytes())
    return h.hexdigest()[:16]


def gather_digests(digest: str, world: World) -> List[str]:
    """Every rank's digest, in rank order (all ranks must call it)."""
    if not world.distributed:
        return [digest]
    out: List[str] = [""] * world.size
    dist.all_gather_object(out, digest)
    return out
