"""`sparc3d-vae train`: AdamW on the VAE loss over the items of one or more jobs.

The run folder holds `config.json` (the settings in force), `loss.csv` (one row per logged
step), `tensorboard/` (when TensorBoard is installed) and `checkpoint.pt` (model, optimizer,
step, RNG state), written every `train.checkpoint_every` steps and at the end. `--resume`
continues from the checkpoint: the batches are a pure function of (seed, step) and the RNG
state is restored, so on CPU a resumed run ends with the same weights as one never stopped.
"""

from __future__ import annotations

import csv
import json
import math
import sys
import time
from pathlib import Path
from typing import Any, Dict, List, Optional

import torch

from .config import Config, load_config
from .data import DataError, Samples, job_info, make_batch
from .loss import vae_loss
from .model import SparconvVAE
from .runtime import (CHECKPOINT_NAME, UsageError, autocast, config_diff, digest_ids,
                      load_checkpoint, pick_device, save_checkpoint, seed_everything)

LOG_FIELDS = ["step", "loss", "occ", "sign", "mag", "delta", "kl", "lr", "cells", "seconds"]


def batch_indices(step: int, n: int, batch_size: int, seed: int) -> List[int]:
    """Items of a step: each epoch is a permutation of the items seeded by (seed, epoch), cut
    into batches of `batch_size` (the last one of an epoch may be smaller)."""
    per_epoch = math.ceil(n / batch_size)
    epoch, j = divmod(step, per_epoch)
    g = torch.Generator().manual_seed(seed * 1_000_003 + epoch)
    perm = torch.randperm(n, generator=g).tolist()
    return perm[j * batch_size:(j + 1) * batch_size]


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


class Progress:
    """A progress line on stderr: rewritten in place on a terminal, one line per log step
    otherwise."""

    def __init__(self, total: int):
        self.total = total
        self.tty = sys.stderr.isatty()
        self.start = time.monotonic()
        self.first_step: Optional[int] = None

    def update(self, step: int, terms: Dict[str, float]) -> None:
        if self.first_step is None:
            self.first_step = step - 1
        done = step - self.first_step
        elapsed = time.monotonic() - self.start
        rate = done / elapsed if elapsed > 0 else 0.0
        eta = (self.total - step) / rate if rate > 0 else 0.0
        line = (f"step {step}/{self.total}  loss {terms['loss']:.4f}  occ {terms['occ']:.4f}  "
                f"sign {terms['sign']:.4f}  mag {terms['mag']:.4f}  δ {terms['delta']:.5f}  "
                f"kl {terms['kl']:.3f}  {rate:.2f} steps/s  ETA {eta / 60:.1f} min")
        if self.tty:
            sys.stderr.write("\r" + line + "\033[K")
        else:
            sys.stderr.write(line + "\n")
        sys.stderr.flush()

    def close(self) -> None:
        if self.tty:
            sys.stderr.write("\n")


def _tensorboard(out: Path):
    try:
        from torch.utils.tensorboard import SummaryWriter
    except Exception:  # TensorBoard is optional: the CSV log is always written
        return None
    return SummaryWriter(str(out / "tensorboard"))


def _rewind_log(path: Path, step: int) -> None:
    """Keeps the log rows up to `step` (a resumed run redoes the steps after its checkpoint)."""
    if not path.exists():
        return
    with open(path, newline="") as f:
        rows = [r for r in csv.DictReader(f) if int(r["step"]) <= step]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, LOG_FIELDS)
        w.writeheader()
        w.writerows(rows)


def train(data: List[str], out: Path, config: Optional[Path], steps: Optional[int],
          device_name: str, resume: bool, seed: Optional[int] = None) -> Dict[str, Any]:
    """Trains (or resumes) a run; returns a summary (steps, final loss terms, seconds)."""
    out = Path(out)
    ckpt_path = out / CHECKPOINT_NAME
    state = None
    if resume:
        state = load_checkpoint(ckpt_path)
        cfg = Config.from_dict(state["config"], str(ckpt_path))
        if config is not None:
            asked = load_config(config)
            asked.model.deformation = cfg.model.deformation
            diff = config_diff(cfg.to_dict()["model"], asked.to_dict()["model"], "model.")
            if diff:
                raise UsageError(f"{config}: its [model] differs from the checkpoint's "
                                 f"({'; '.join(diff)}); start a new run with another --out")
            cfg.loss, cfg.train = asked.loss, asked.train
    else:
        if ckpt_path.exists():
            raise UsageError(f"{out} already holds a checkpoint: pass --resume to continue it, "
                             "or choose another --out")
        cfg = load_config(config)
    if steps is not None:
        cfg.train.steps = steps
    if seed is not None:
        if state is not None and seed != cfg.train.seed:
            raise UsageError(f"--seed {seed}: the run was started with seed {cfg.train.seed}")
        cfg.train.seed = seed
    device = pick_device(device_name)
    if cfg.train.threads > 0:
        torch.set_num_threads(cfg.train.threads)

    info = job_info(data)
    if state is not None and cfg.model.deformation != info.deformation:
        raise UsageError(f"the checkpoint's model {'reads' if cfg.model.deformation else 'has no'} "
                         f"deformation, but the data {'has' if info.deformation else 'has none'}")
    cfg.model.deformation = info.deformation
    cfg.validate()
    samples = Samples(info, cache=cfg.train.cache_items)
    if len(samples) == 0:
        raise DataError(f"{', '.join(data)}: no ok items to train on")
    ids_digest = digest_ids(samples.ids)
    if state is not None and state.get("data", {}).get("ids_digest") != ids_digest:
        print(f"warning: the data differs from the checkpoint's ({len(samples)} items now); "
              "the resumed run will not repeat the original one", file=sys.stderr)

    seed_everything(cfg.train.seed)
    model = SparconvVAE(cfg.model).to(device)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.train.lr, weight_decay=cfg.train.weight_decay)
    start = 0
    if state is not None:
        model.load_state_dict(state["model"])
        opt.load_state_dict(state["optimizer"])
        start = int(state["step"])
        torch.set_rng_state(state["rng"]["torch"])
        if device.type == "cuda" and state["rng"].get("cuda") is not None:
            torch.cuda.set_rng_state(state["rng"]["cuda"])

    out.mkdir(parents=True, exist_ok=True)
    (out / "config.json").write_text(json.dumps(cfg.to_dict(), indent=2) + "\n")
    log_path = out / "loss.csv"
    if state is not None:
        _rewind_log(log_path, start)
    new_log = not log_path.exists()
    log_file = open(log_path, "a", newline="")
    log = csv.DictWriter(log_file, LOG_FIELDS)
    if new_log:
        log.writeheader()
    tb = _tensorboard(out)

    def checkpoint(step: int) -> None:
        save_checkpoint(ckpt_path, {
            "config": cfg.to_dict(), "model": model.state_dict(), "optimizer": opt.state_dict(),
            "step": step,
            "rng": {"torch": torch.get_rng_state(),
                    "cuda": torch.cuda.get_rng_state() if device.type == "cuda" else None},
            "data": {"ids_digest": ids_digest, "items": len(samples),
                     "resolutions": info.resolutions}})

    t = cfg.train
    progress = Progress(t.steps)
    skipped: Dict[str, int] = {}
    terms: Dict[str, float] = {}
    began = time.monotonic()
    model.train()
    for step in range(start, t.steps):
        lr = learning_rate(step, cfg)
        for group in opt.param_groups:
            group["lr"] = lr
        batch = [samples[i] for i in batch_indices(step, len(samples), t.batch_size, t.seed)]
        fits = [s for s in batch if len(s.cells) <= t.max_cells_per_batch]
        for s in batch:
            if len(s.cells) > t.max_cells_per_batch and s.id not in skipped:
                skipped[s.id] = len(s.cells)
                print(f"\nwarning: item {s.id!r} has {len(s.cells)} cells, more than "
                      f"train.max_cells_per_batch = {t.max_cells_per_batch}; skipped",
                      file=sys.stderr)
        if not fits:
            continue
        total_cells = sum(len(s.cells) for s in fits)
        opt.zero_grad(set_to_none=True)
        sums: Dict[str, float] = {}
        for part in split_parts(fits, t.max_cells_per_batch):
            chosen = [fits[i] for i in part]
            x = make_batch(chosen, device)
            weight = len(x.coords) / total_cells
            with autocast(device):
                dec, mean, logvar, structure = model(x, sample=True, teacher_forcing=t.teacher_forcing)
                loss, part_terms = vae_loss(dec, logvar, mean, structure, x.feats, cfg.loss)
            (loss * weight).backward()
            for k, v in part_terms.items():
                sums[k] = sums.get(k, 0.0) + v * weight
        if t.grad_clip > 0:
            torch.nn.utils.clip_grad_norm_(model.parameters(), t.grad_clip)
        opt.step()
        terms = sums
        done = step + 1
        if done % t.log_every == 0 or done == t.steps:
            row = {**{k: f"{v:.6g}" for k, v in terms.items()}, "step": done, "lr": f"{lr:.6g}",
                   "cells": total_cells, "seconds": f"{time.monotonic() - began:.2f}"}
            log.writerow(row)
            log_file.flush()
            if tb is not None:
                for k, v in terms.items():
                    tb.add_scalar(f"loss/{k}", v, done)
                tb.add_scalar("lr", lr, done)
            progress.update(done, terms)
        if done % t.checkpoint_every == 0 or done == t.steps:
            checkpoint(done)
    progress.close()
    log_file.close()
    if tb is not None:
        tb.close()
    if start >= t.steps and not ckpt_path.exists():
        checkpoint(start)
    seconds = time.monotonic() - began
    return {"steps": t.steps, "resumed_from": start, "terms": terms, "seconds": seconds,
            "steps_per_second": (t.steps - start) / seconds if seconds > 0 else 0.0,
            "skipped": skipped, "items": len(samples)}
