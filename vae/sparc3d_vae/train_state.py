"""What a training run holds between steps and keeps in its checkpoint: the model, AdamW and
the EMA, made new (from `--init-from`'s weights when given) or as a checkpoint left them
(`model_and_optimizer`), and the checkpoint written from them (`CheckpointSaver`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Dict, Optional

import torch

from . import distributed, presets
from .config import Config
from .ema import EMA
from .model import SparconvVAE
from .run_start import InitWeights
from .runtime import load_weights, save_checkpoint


def model_and_optimizer(cfg: Config, state: Optional[Dict[str, Any]], init: Optional[InitWeights],
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


class CheckpointSaver:
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
