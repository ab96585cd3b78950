"""`sparc3d-vae train`: AdamW on the VAE loss over the items of one or more jobs.

A new run's settings are the ones measured for the jobs' resolution, with `--config`'s keys on
top (`presets` says how they are chosen); a line on stderr says which it took. The run folder
holds `config.json` (the settings in force, and under `settings` where they came from),
`loss.csv` (one row per logged step), `tensorboard/` (when TensorBoard is installed) and
`checkpoint.pt` (model, optimizer, step, RNG state, settings), written every
`train.checkpoint_every` steps and at the end. `--resume`
continues from the checkpoint: the batches and the latent noise are pure functions of (seed,
step, rank), so on CPU a resumed run ends with the same weights as one never stopped.

Several processes (`torchrun --nproc_per_node N -m sparc3d_vae train ...`) share each global
batch; `distributed` says how.

This module is the loop and its steps; around it, by role: `run_start` (what a run starts
from: its settings, a resumed run's refusals), `train_state` (model, optimizer, EMA, the
checkpoint), `schedule` (each step's batch and learning rate), `ema`, and `run_log` (the
progress line, loss.csv, TensorBoard).
"""

from __future__ import annotations

import contextlib
import sys
import time
from pathlib import Path
from typing import Any, Dict, List, Optional

import numpy as np

import torch
from torch.nn.parallel import DistributedDataParallel

from . import augment, distributed
from .config import Config, TrainConfig
from .data import DataError, Sample, Samples, make_batch
from .ema import EMA
from .loss import LOSS_TERMS, vae_loss
from .run_log import LOG_FIELDS, Progress, RunLog
from .run_start import (TRAJECTORY_KEYS, InitWeights, RunStart, apply_options, start_run,
                        take_deformation)
from .runtime import (CHECKPOINT_NAME, UsageError, autocast, digest_ids, memory_guard,
                      pick_device, seed_everything)
from .sampling import choose
from .schedule import batch_indices, learning_rate, split_parts
from .train_state import CheckpointSaver, model_and_optimizer

__all__ = ["EMA", "LOG_FIELDS", "LOSS_TERMS", "TRAJECTORY_KEYS", "InitWeights", "Progress",
           "batch_indices", "learning_rate", "split_parts", "train"]


def train(data: List[str], out: Path, config: Optional[Path], steps: Optional[int],
          device_name: str, resume: bool, seed: Optional[int] = None,
          hold_out: Optional[int] = None, hold_out_seed: Optional[int] = None,
          init_from: Optional[Path] = None) -> Dict[str, Any]:
    """Trains (or resumes) a run; returns a summary (steps, final loss terms, seconds). Under
    torchrun every process calls it (see `distributed`); rank 0 writes the run folder.
    `config`: a TOML file whose keys go on top of the jobs' measured settings (`presets`), or
    of the checkpoint's when resuming. `seed`, `hold_out`, `hold_out_seed` override the
    config's train keys of those names; `init_from` (a checkpoint or run folder) gives a new
    run its starting weights."""
    out = Path(out)
    try:
        world = distributed.world_from_env()
    except ValueError as e:
        raise UsageError(str(e)) from None
    ckpt_path = out / CHECKPOINT_NAME
    start = start_run(data, ckpt_path, config, resume, init_from, world)
    apply_options(start, steps, seed, hold_out, hold_out_seed)
    cfg = start.cfg
    cfg.validate()
    if cfg.train.batch_size % world.size:
        raise UsageError(f"train.batch_size = {cfg.train.batch_size} does not divide among "
                         f"{world.size} processes (WORLD_SIZE): use a multiple of {world.size}")
    device = pick_device(device_name, world.local_rank if world.distributed else None)
    if cfg.train.threads > 0:
        torch.set_num_threads(cfg.train.threads)
    take_deformation(start)
    cfg.validate()
    samples = Samples(start.info, cache=cfg.train.cache_items)
    if len(samples) == 0:
        raise DataError(f"{', '.join(data)}: no ok items to train on")
    pool = _training_pool(samples, cfg, data)
    ids_digest = digest_ids(samples.ids)
    if world.main and start.state is not None and start.state.get("data", {}).get("ids_digest") != ids_digest:
        print(f"warning: the data differs from the checkpoint's ({len(samples)} items now); "
              "the resumed run will not repeat the original one", file=sys.stderr)

    if world.main:
        print(start.settings.message(resumed=start.state is not None), file=sys.stderr)
    distributed.init(world, device)
    try:
        result = _loop(start, samples, pool, ids_digest, out, ckpt_path, device, world)
        # The ranks meet before leaving the group: gloo aborts a process (SIGABRT in its
        # teardown) when one rank destroys the group while a peer still has a collective or a
        # send in flight. Only on success: a failed peer would leave the others waiting.
        distributed.barrier(world)
        return result
    finally:
        distributed.shutdown(world)


def _training_pool(samples: Samples, cfg: Config, data: List[str]) -> List[int]:
    """The positions of the items trained on: all but the `train.hold_out` ones `evaluate`
    would sample with `train.hold_out_seed`."""
    pool = list(range(len(samples)))
    if cfg.train.hold_out:
        held = set(choose(samples.ids, cfg.train.hold_out, cfg.train.hold_out_seed))
        pool = [i for i, item_id in enumerate(samples.ids) if item_id not in held]
        if not pool:
            raise DataError(f"{', '.join(data)}: train.hold_out = {cfg.train.hold_out} leaves "
                            f"none of its {len(samples)} items to train on")
    return pool


def _loop(start: RunStart, samples: Samples, pool: List[int], ids_digest: str, out: Path,
          ckpt_path: Path, device: torch.device, world: distributed.World) -> Dict[str, Any]:
    """The optimisation steps of `train` (in the process group when there is one)."""
    cfg, state, init = start.cfg, start.state, start.init
    seed_everything(cfg.train.seed)
    model, opt, ema, first = model_and_optimizer(cfg, state, init, device)
    # Every rank starts from the same weights (same seed); DDP checks the shapes and
    # broadcasts rank 0's weights once more.
    net = DistributedDataParallel(model) if world.distributed else model
    log = RunLog(out, cfg, start.settings, state is not None, first) if world.main else None
    saver = CheckpointSaver(ckpt_path, cfg, start.settings, model, opt, ema, device, world,
                            init.record() if init is not None else (state or {}).get("init_from"),
                            {"ids_digest": ids_digest, "items": len(samples),
                             "resolutions": start.info.resolutions})
    t = cfg.train
    if world.main and init is not None and first == 0:
        at = ", ".join(f"{r}³" for r in init.resolutions or []) or "an unrecorded resolution"
        print(f"starting from the weights of {init.path} (step {init.step}, trained at {at})",
              file=sys.stderr)
    progress = Progress(t.steps) if world.main else None
    skipped: Dict[str, int] = {}
    terms: Dict[str, float] = {}
    began = time.monotonic()
    cells_done = 0
    model.train()
    for step in range(first, t.steps):
        lr = learning_rate(step, cfg)
        for group in opt.param_groups:
            group["lr"] = lr
        # The latent noise of a step is a function of (seed, step, rank): a resumed run draws
        # the same noise as an uninterrupted one.
        torch.manual_seed((t.seed * 1_000_003 + step) * 4099 + world.rank)
        fits = _step_items(samples, pool, step, t, world, skipped)
        local_cells = sum(len(s.cells) for s in fits)
        total_cells = int(distributed.all_sum(torch.tensor([local_cells], dtype=torch.int64), world))
        if total_cells == 0:
            continue
        opt.zero_grad(set_to_none=True)
        sums = _forward_backward(net, fits, local_cells, total_cells, step, cfg, device, world)
        if t.grad_clip > 0:
            torch.nn.utils.clip_grad_norm_(model.parameters(), t.grad_clip)
        opt.step()
        if ema is not None:
            ema.update(step)
        terms = dict(zip(LOSS_TERMS, distributed.all_sum(sums, world).tolist()))
        cells_done += total_cells
        done = step + 1
        if log is not None and (done % t.log_every == 0 or done == t.steps):
            log.write(done, terms, lr, total_cells, time.monotonic() - began)
            progress.update(done, terms)
        if done % t.checkpoint_every == 0 or done == t.steps:
            saver.save(done)
    if progress is not None:
        progress.close()
    if log is not None:
        log.close()
    if first >= t.steps and not ckpt_path.exists():
        saver.save(first)
    seconds = time.monotonic() - began
    return {"steps": t.steps, "resumed_from": first, "terms": terms, "seconds": seconds,
            "steps_per_second": (t.steps - first) / seconds if seconds > 0 else 0.0,
            "skipped": skipped, "items": len(pool), "world_size": world.size,
            "peak_gpu_bytes": torch.cuda.max_memory_allocated(device) if device.type == "cuda" else None,
            "cells_per_second": cells_done / seconds if seconds > 0 else 0.0}


def _placeholder(width: int) -> Sample:
    """One cell with zero features: what a rank trains on (with weight 0) when every item of
    its share is over the cell budget, so that it still joins the gradient average."""
    return Sample("", {}, np.zeros((1, 3), np.int32), np.zeros((1, width), np.float32))


def _step_items(samples: Samples, pool: List[int], step: int, t: TrainConfig, world: distributed.World,
                skipped: Dict[str, int]) -> List[Sample]:
    """This rank's share of a step's global batch (rotated when `augment_rotations`), less the
    items over `max_cells_per_batch`, each named once in a warning and in `skipped`."""
    everyone = [pool[j] for j in batch_indices(step, len(pool), t.batch_size, t.seed)]
    mine = distributed.shard(list(enumerate(everyone)), world)
    if t.augment_rotations:
        batch = [augment.rotate_sample(samples[i], augment.rotation_for(t.seed, step, pos))
                 for pos, i in mine]
    else:
        batch = [samples[i] for _, i in mine]
    fits = [s for s in batch if len(s.cells) <= t.max_cells_per_batch]
    for s in batch:
        if len(s.cells) > t.max_cells_per_batch and s.id not in skipped:
            skipped[s.id] = len(s.cells)
            print(f"\nwarning: item {s.id!r} has {len(s.cells)} cells, more than "
                  f"train.max_cells_per_batch = {t.max_cells_per_batch}; skipped",
                  file=sys.stderr)
    return fits


def _forward_backward(net, fits: List[Sample], local_cells: int, total_cells: int, step: int,
                      cfg: Config, device: torch.device, world: distributed.World) -> torch.Tensor:
    """The gradients of a step's loss on this rank's items, in parts of at most
    `max_cells_per_batch` cells; returns the loss terms weighted by this rank's share."""
    t = cfg.train
    # Each part's loss is weighted by its share of the global batch's cells; DDP averages
    # the ranks' gradients (divides by the world size), hence the factor world.size.
    parts = [[fits[i] for i in part] for part in split_parts(fits, t.max_cells_per_batch)]
    if not parts:
        parts = [[_placeholder(8 + (24 if cfg.model.deformation else 0))]]
    sums = torch.zeros(len(LOSS_TERMS), dtype=torch.float64)
    for p, chosen in enumerate(parts):
        x = make_batch(chosen, device)
        weight = len(x.coords) / total_cells if local_cells else 0.0
        sync = p == len(parts) - 1 or not world.distributed
        what = f"step {step + 1}, a batch part of {len(chosen)} item(s)"
        with memory_guard(what, len(x.coords), t.max_cells_per_batch, device), \
                (contextlib.nullcontext() if sync else net.no_sync()):
            with autocast(device):
                dec, mean, logvar, structure = net(x, sample=True, teacher_forcing=t.teacher_forcing,
                                                  siblings=t.structure == "siblings")
                loss, part_terms = vae_loss(dec, logvar, mean, structure, x.feats, cfg.loss)
            (loss * (weight * world.size)).backward()
        sums += torch.tensor([part_terms[k] for k in LOSS_TERMS], dtype=torch.float64) * weight
    return sums
