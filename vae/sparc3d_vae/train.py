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
"""

from __future__ import annotations

import contextlib
import csv
import functools
import json
import math
import sys
import time
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

import torch
from torch.nn.parallel import DistributedDataParallel

from . import augment, distributed, presets
from .config import Config, TrainConfig, load_config
from .data import DataError, Sample, Samples, job_info, make_batch
from .loss import vae_loss
from .model import SparconvVAE
from .runtime import (CHECKPOINT_NAME, UsageError, autocast, checkpoint_path, config_diff,
                      digest_ids, load_checkpoint, load_weights, memory_guard, pick_device,
                      save_checkpoint, seed_everything)

#: The loss terms `vae_loss` returns, in the log's order.
LOSS_TERMS = ["loss", "occ", "sign", "mag", "delta", "kl"]
LOG_FIELDS = ["step", *LOSS_TERMS, "lr", "cells", "seconds"]


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


class Progress:
    """A progress line on stderr: rewritten in place on a terminal, one line per log step
    otherwise."""

    def __init__(self, total: int):
        self.total = total
        self.tty = sys.stderr.isatty()
        self.start = time.monotonic()
        self.first_step: Optional[int] = None

    def update(self, step: int, terms: Dict[str, float]) -> None:
        """Shows step `step`'s loss terms, rate and time left."""
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
        """Ends the line rewritten in place."""
        if self.tty:
            sys.stderr.write("\n")


class EMA:
    """Exponential moving average of the weights (float32), what inference loads when the
    checkpoint holds it: w̄ ← d·w̄ + (1 − d)·w after every step, with d = min(decay,
    (1 + step) / (10 + step)) so early weights fade fast (the warm-up of TensorFlow's
    `ExponentialMovingAverage(num_updates=...)`). TRELLIS evaluates its VAEs with an EMA too."""

    def __init__(self, model: torch.nn.Module, decay: float):
        self.model = model
        self.decay = decay
        self.shadow = {k: v.detach().float().clone() for k, v in model.state_dict().items()}

    @torch.no_grad()
    def update(self, step: int) -> None:
        """Moves the average towards the model's weights after step `step`."""
        d = min(self.decay, (1 + step) / (10 + step))
        for k, v in self.model.state_dict().items():
            self.shadow[k].mul_(d).add_(v.detach().float(), alpha=1 - d)

    def state_dict(self) -> Dict[str, torch.Tensor]:
        """A copy of the averaged weights, as a model's `state_dict`."""
        return {k: v.clone() for k, v in self.shadow.items()}

    def load(self, state: Dict[str, torch.Tensor]) -> None:
        """Takes the averaged weights of a checkpoint (float32, on the model's device)."""
        self.shadow = {k: v.detach().float().clone().to(self.shadow[k].device) for k, v in state.items()}


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


#: [train] keys that decide which batches a run sees and how it learns them: a resumed run
#: must keep them (the others, such as `steps`, `lr` or `checkpoint_every`, may change).
TRAJECTORY_KEYS = ("batch_size", "seed", "teacher_forcing", "structure", "augment_rotations",
                   "ema_decay", "hold_out", "hold_out_seed")


def _placeholder(width: int) -> Sample:
    """One cell with zero features: what a rank trains on (with weight 0) when every item of
    its share is over the cell budget, so that it still joins the gradient average."""
    return Sample("", {}, np.zeros((1, 3), np.int32), np.zeros((1, width), np.float32))


def _asked_config(cfg: Config, config: Path, base_name: str) -> Tuple[Config, List[str]]:
    """`config`'s keys on top of `cfg` (called `base_name` in errors), keeping `cfg`'s
    deformation (which the data decides), and the [model] keys in which the result differs
    from `cfg` (dotted, with both values)."""
    asked = load_config(config, cfg, base_name)
    asked.model.deformation = cfg.model.deformation
    return asked, config_diff(cfg.to_dict()["model"], asked.to_dict()["model"], "model.")


def _resume_config(state: Dict[str, Any], ckpt_path: Path, config: Optional[Path],
                   world: distributed.World) -> Tuple[Config, presets.Settings]:
    """The config of a resumed run and where it came from: the checkpoint's, with the keys
    `config` sets on top when given. Refused, naming the keys: another [model], another value
    of a `TRAJECTORY_KEYS` key, another world size."""
    cfg = Config.from_dict(state["config"], str(ckpt_path))
    settings = presets.Settings.from_record(state.get("settings"))
    trained_world = int(state.get("world_size", 1))
    if trained_world != world.size:
        raise UsageError(f"{ckpt_path}: trained with world size {trained_world}, resumed with "
                         f"{world.size} (WORLD_SIZE; torchrun --nproc_per_node): the batches "
                         "would differ; resume with the same number of processes")
    if config is None:
        return cfg, settings
    asked, diff = _asked_config(cfg, config, f"the settings of {ckpt_path}")
    old_t, new_t = cfg.to_dict()["train"], asked.to_dict()["train"]
    diff += config_diff({k: old_t[k] for k in TRAJECTORY_KEYS},
                        {k: new_t[k] for k in TRAJECTORY_KEYS}, "train.")
    if diff:
        raise UsageError(f"{config}: differs from the checkpoint {ckpt_path} in "
                         f"{'; '.join(diff)} ([model] differs or the batches would); start a new "
                         "run with another --out")
    settings.configs.append(str(config))
    return asked, settings


class InitWeights:
    """The weights a new run starts from (`--init-from`): another run's EMA weights (its raw
    weights when it kept no average), whatever resolution it was trained at: the sparse
    convolutions' kernels do not depend on the grid's size, so a model trained at 64³ is a
    starting point at 128³ (docs/VAE.md, "128³ on CPU")."""

    def __init__(self, path: Path, state: Dict[str, Any]):
        self.path = path
        self.config = Config.from_dict(state["config"], str(path))
        self.weights = state.get("ema") or state["model"]
        self.step = int(state.get("step", 0))
        self.resolutions = state.get("data", {}).get("resolutions")

    def record(self) -> Dict[str, Any]:
        """What the new run's checkpoint says about where it started."""
        return {"path": str(self.path), "step": self.step, "resolutions": self.resolutions,
                "weights_digest": distributed.weights_digest(self.weights)}


def _new_config(resolutions: List[int], config: Optional[Path],
                init: Optional[InitWeights]) -> Tuple[Config, presets.Settings]:
    """The config of a new run and where it came from (`presets`): the measured settings for
    the jobs' `resolutions`, with the [model] of `init` when starting from its weights, then
    the keys `config` sets. With `init`, a [model] key of `config` that differs from its
    model is refused, naming the keys: the weights would not fit."""
    cfg, settings = presets.for_jobs(resolutions)
    if init is not None:
        cfg.model = init.config.model
        settings.model_from = str(init.path)
    if config is None:
        return cfg, settings
    asked, diff = _asked_config(cfg, config, settings.base())
    if init is not None and diff:
        raise UsageError(f"{config}: its [model] differs from the one of --init-from {init.path} "
                         f"in {'; '.join(diff)}: the weights would not fit")
    settings.configs.append(str(config))
    return asked, settings


def _start(data: List[str], ckpt_path: Path, config: Optional[Path], resume: bool,
           init_from: Optional[Path], world: distributed.World):
    """What a run starts from: (the checkpoint's state when resuming, the `--init-from`
    weights, the jobs, the config, where the config came from)."""
    if resume and init_from is not None:
        raise UsageError("--init-from starts a new run from another's weights, --resume "
                         "continues this one: pass one of them")
    if resume:
        state = load_checkpoint(ckpt_path)
        cfg, settings = _resume_config(state, ckpt_path, config, world)
        return state, None, job_info(data), cfg, settings
    if ckpt_path.exists():
        raise UsageError(f"{ckpt_path.parent} already holds a checkpoint: pass --resume to "
                         "continue it, or choose another --out")
    init = None
    if init_from is not None:
        init_path = checkpoint_path(init_from)
        init = InitWeights(init_path, load_checkpoint(init_path))
    info = job_info(data)
    cfg, settings = _new_config(info.resolutions, config, init)
    return None, init, info, cfg, settings


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
    state, init, info, cfg, settings = _start(data, ckpt_path, config, resume, init_from, world)
    if steps is not None:
        cfg.train.steps = steps
    for flag, key, value in (("--seed", "seed", seed), ("--hold-out", "hold_out", hold_out),
                             ("--hold-out-seed", "hold_out_seed", hold_out_seed)):
        if value is None:
            continue
        if state is not None and value != getattr(cfg.train, key):
            raise UsageError(f"{flag} {value}: the run was started with train.{key} = "
                             f"{getattr(cfg.train, key)}")
        setattr(cfg.train, key, value)
    cfg.validate()
    if cfg.train.batch_size % world.size:
        raise UsageError(f"train.batch_size = {cfg.train.batch_size} does not divide among "
                         f"{world.size} processes (WORLD_SIZE): use a multiple of {world.size}")
    device = pick_device(device_name, world.local_rank if world.distributed else None)
    if cfg.train.threads > 0:
        torch.set_num_threads(cfg.train.threads)

    if (state is not None or init is not None) and cfg.model.deformation != info.deformation:
        whose = "the checkpoint's" if init is None else f"--init-from {init.path}: its"
        raise UsageError(f"{whose} model {'reads' if cfg.model.deformation else 'has no'} "
                         f"deformation, but the data {'has' if info.deformation else 'has none'}")
    cfg.model.deformation = info.deformation
    cfg.validate()
    samples = Samples(info, cache=cfg.train.cache_items)
    if len(samples) == 0:
        raise DataError(f"{', '.join(data)}: no ok items to train on")
    pool = list(range(len(samples)))
    if cfg.train.hold_out:
        from .infer import choose

        held = set(choose(samples.ids, cfg.train.hold_out, cfg.train.hold_out_seed))
        pool = [i for i, item_id in enumerate(samples.ids) if item_id not in held]
        if not pool:
            raise DataError(f"{', '.join(data)}: train.hold_out = {cfg.train.hold_out} leaves "
                            f"none of its {len(samples)} items to train on")
    ids_digest = digest_ids(samples.ids)
    if world.main and state is not None and state.get("data", {}).get("ids_digest") != ids_digest:
        print(f"warning: the data differs from the checkpoint's ({len(samples)} items now); "
              "the resumed run will not repeat the original one", file=sys.stderr)

    if world.main:
        print(settings.message(resumed=state is not None), file=sys.stderr)
    distributed.init(world, device)
    try:
        return _loop(cfg, settings, state, init, samples, pool, info, ids_digest, out, ckpt_path,
                     device, world)
    finally:
        distributed.shutdown(world)


def _loop(cfg: Config, settings: presets.Settings, state: Optional[Dict[str, Any]],
          init: Optional[InitWeights], samples: Samples, pool: List[int], info, ids_digest: str,
          out: Path, ckpt_path: Path, device: torch.device,
          world: distributed.World) -> Dict[str, Any]:
    """The optimisation steps of `train` (in the process group when there is one)."""
    seed_everything(cfg.train.seed)
    model, opt, ema, start = _model_and_optimizer(cfg, state, init, device)
    # Every rank starts from the same weights (same seed); DDP checks the shapes and
    # broadcasts rank 0's weights once more.
    net = DistributedDataParallel(model) if world.distributed else model
    log = _RunLog(out, cfg, settings, state is not None, start) if world.main else None
    saver = _Saver(ckpt_path, cfg, settings, model, opt, ema, device, world,
                   init.record() if init is not None else (state or {}).get("init_from"),
                   {"ids_digest": ids_digest, "items": len(samples), "resolutions": info.resolutions})
    t = cfg.train
    if world.main and init is not None and start == 0:
        at = ", ".join(f"{r}³" for r in init.resolutions or []) or "an unrecorded resolution"
        print(f"starting from the weights of {init.path} (step {init.step}, trained at {at})",
              file=sys.stderr)
    progress = Progress(t.steps) if world.main else None
    skipped: Dict[str, int] = {}
    terms: Dict[str, float] = {}
    began = time.monotonic()
    cells_done = 0
    model.train()
    for step in range(start, t.steps):
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
    if start >= t.steps and not ckpt_path.exists():
        saver.save(start)
    seconds = time.monotonic() - began
    return {"steps": t.steps, "resumed_from": start, "terms": terms, "seconds": seconds,
            "steps_per_second": (t.steps - start) / seconds if seconds > 0 else 0.0,
            "skipped": skipped, "items": len(pool), "world_size": world.size,
            "peak_gpu_bytes": torch.cuda.max_memory_allocated(device) if device.type == "cuda" else None,
            "cells_per_second": cells_done / seconds if seconds > 0 else 0.0}


def _model_and_optimizer(cfg: Config, state: Optional[Dict[str, Any]], init: Optional[InitWeights],
                         device: torch.device):
    """The model (from `--init-from`'s weights when given), AdamW, the EMA when asked, and the
    first step: all as the checkpoint left them when resuming."""
    model = SparconvVAE(cfg.model).to(device)
    if init is not None:
        load_weights(model, init.weights, f"--init-from {init.path}")
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.train.lr, weight_decay=cfg.train.weight_decay)
    ema = EMA(model, cfg.train.ema_decay) if cfg.train.ema_decay > 0 else None
    start = 0
    if state is not None:
        model.load_state_dict(state["model"])
        opt.load_state_dict(state["optimizer"])
        start = int(state["step"])
        if ema is not None:
            ema.load(state.get("ema") or model.state_dict())
    return model, opt, ema, start


class _RunLog:
    """What rank 0 writes as it goes: `config.json`, `loss.csv` (rewound to the checkpoint's
    step when resuming) and TensorBoard's scalars when it is installed."""

    def __init__(self, out: Path, cfg: Config, settings: presets.Settings, resumed: bool,
                 start: int):
        out.mkdir(parents=True, exist_ok=True)
        written = {**cfg.to_dict(), "settings": settings.record()}
        (out / "config.json").write_text(json.dumps(written, indent=2) + "\n")
        log_path = out / "loss.csv"
        if resumed:
            _rewind_log(log_path, start)
        new_log = not log_path.exists()
        self.file = open(log_path, "a", newline="")
        self.csv = csv.DictWriter(self.file, LOG_FIELDS)
        if new_log:
            self.csv.writeheader()
        self.tb = _tensorboard(out)

    def write(self, done: int, terms: Dict[str, float], lr: float, cells: int, seconds: float) -> None:
        """One logged step: a row of loss.csv (flushed) and its TensorBoard scalars."""
        row = {**{k: f"{v:.6g}" for k, v in terms.items()}, "step": done, "lr": f"{lr:.6g}",
               "cells": cells, "seconds": f"{seconds:.2f}"}
        self.csv.writerow(row)
        self.file.flush()
        if self.tb is not None:
            for k, v in terms.items():
                self.tb.add_scalar(f"loss/{k}", v, done)
            self.tb.add_scalar("lr", lr, done)

    def close(self) -> None:
        """Closes loss.csv and TensorBoard's writer."""
        self.file.close()
        if self.tb is not None:
            self.tb.close()


class _Saver:
    """Writes the run's checkpoint (rank 0), once every rank's weights are known to agree."""

    def __init__(self, path: Path, cfg: Config, settings: presets.Settings, model: SparconvVAE,
                 opt: torch.optim.Optimizer, ema: Optional[EMA], device: torch.device,
                 world: distributed.World, init_record: Optional[Dict[str, Any]],
                 data: Dict[str, Any]):
        self.path, self.cfg, self.settings, self.model = path, cfg, settings, model
        self.opt, self.ema = opt, ema
        self.device, self.world, self.init_record, self.data = device, world, init_record, data

    def save(self, step: int) -> None:
        """The checkpoint at `step`: config, weights, optimizer, EMA, RNG state and the data's
        digest; a RuntimeError when the ranks' weights differ (a bug)."""
        world = self.world
        digests = distributed.gather_digests(distributed.weights_digest(self.model.state_dict()), world)
        if len(set(digests)) > 1:
            raise RuntimeError(f"the ranks' weights differ at step {step} ({digests}): a bug")
        if world.main:
            save_checkpoint(self.path, {
                "config": self.cfg.to_dict(), "settings": self.settings.record(),
                "model": self.model.state_dict(),
                "optimizer": self.opt.state_dict(), "step": step, "world_size": world.size,
                "rank_digests": digests,
                **({"ema": self.ema.state_dict()} if self.ema is not None else {}),
                **({"init_from": self.init_record} if self.init_record else {}),
                "rng": {"torch": torch.get_rng_state(),
                        "cuda": torch.cuda.get_rng_state() if self.device.type == "cuda" else None},
                "data": self.data})
        distributed.barrier(world)


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
