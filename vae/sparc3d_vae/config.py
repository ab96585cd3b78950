"""The VAE's settings: model shape, loss weights, training. The base defaults live here and are
written out, with the reasons, in `vae/vae.toml` (a test keeps the two equal). `train` starts
from the measured settings for the job's resolution (`sparc3d_vae/configs/<N>.toml` on top of
these, chosen by `presets`), and `--config FILE` overrides any key of any section on top of that.

Sections: `[model]` decides the network (a checkpoint records it and refuses another one),
`[loss]` the λs of the loss, `[train]` the optimisation.
"""

from __future__ import annotations

import copy
import dataclasses
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python < 3.11 only
    import tomli as tomllib


class ConfigError(ValueError):
    """A config file or value that cannot be used; the message names the file and key."""


@dataclass
class ModelConfig:
    """Shape of the network (see docs/VAE.md, "Model")."""

    #: Channels per level, full resolution first; one level per halving, so
    #: `len(channels) = log2(downsample) + 1`.
    channels: List[int] = field(default_factory=lambda: [32, 32, 64, 64, 64])
    #: Latent grid = resolution / downsample (16, or 8 for finer latents).
    downsample: int = 16
    #: Channels of the latent per voxel (TRELLIS' structured latent uses 8).
    latent_channels: int = 8
    #: Residual blocks per level (full resolution first), in the encoder and in the decoder.
    #: None at full resolution by default: that level holds most voxels, and its features come
    #: from the level above through the 2×2×2 down / subdivision convolutions.
    blocks: List[int] = field(default_factory=lambda: [0, 1, 1, 1, 1])
    #: Local attention blocks at the coarsest level, in the encoder and in the decoder.
    attention_blocks: int = 1
    #: Heads of the local attention.
    heads: int = 4
    #: Channels of the 3×3×3 submanifold convolution at full resolution in the decoder, just
    #: before the heads (0: none, each cell's corner values then come from its parent's
    #: feature through the subdivision alone).
    finest_conv: int = 0
    #: Whether the model reads and predicts the deformation δ (set from the job's config).
    deformation: bool = True

    def levels(self) -> int:
        """Number of halvings between the full grid and the latent grid."""
        return self.downsample.bit_length() - 1


@dataclass
class LossConfig:
    """Weights λ of the loss terms (docs/VAE.md, "Loss")."""

    occ: float = 1.0
    sign: float = 1.0
    mag: float = 1.0
    delta: float = 1.0
    kl: float = 1e-6


@dataclass
class TrainConfig:
    """Optimisation settings."""

    lr: float = 2e-3
    weight_decay: float = 0.0
    warmup_steps: int = 20
    #: The learning rate decays along a cosine to `final_lr_fraction · lr` at the last step.
    final_lr_fraction: float = 0.05
    batch_size: int = 4
    steps: int = 2000
    grad_clip: float = 1.0
    checkpoint_every: int = 100
    log_every: int = 10
    seed: int = 0
    #: Decoder keeps the true children during training (teacher forcing); false: its own.
    teacher_forcing: bool = True
    #: Which cells the decoder's last level holds while training: "true" (the true cells,
    #: teacher forcing) or "siblings" (every child of the true parents: the cells it may wrongly
    #: add at inference are trained too, where their corners are known vertices).
    structure: str = "siblings"
    #: Rotate each training item by one of the 24 rotations of the cube (exact on the grid).
    augment_rotations: bool = False
    #: Decay of the exponential moving average of the weights that inference uses (0: none;
    #: the decay ramps up as min(decay, (1 + step) / (10 + step))).
    ema_decay: float = 0.0
    #: Items left out of training: those `sparc3d-vae evaluate --sample hold_out --seed
    #: hold_out_seed` (and `sparc3d eval --sample`) picks from the same jobs, so that one
    #: converted job gives a training set and unseen items (0: train on every item).
    hold_out: int = 0
    hold_out_seed: int = 0
    #: CPU threads for torch (0: torch's default).
    threads: int = 2
    #: Cells one forward pass may hold; a larger batch is split into parts whose gradients
    #: are summed, and a single item larger than this is skipped with a message.
    max_cells_per_batch: int = 400_000
    #: Keep decoded items in memory between epochs.
    cache_items: bool = True


@dataclass
class Config:
    """All settings."""

    model: ModelConfig = field(default_factory=ModelConfig)
    loss: LossConfig = field(default_factory=LossConfig)
    train: TrainConfig = field(default_factory=TrainConfig)

    def to_dict(self) -> Dict[str, Any]:
        """Plain nested dict (for checkpoints and logs)."""
        return dataclasses.asdict(self)

    def copy(self) -> "Config":
        """An independent copy (its lists are not shared)."""
        return copy.deepcopy(self)

    @staticmethod
    def from_dict(d: Dict[str, Any], source: str = "config",
                  base: Optional["Config"] = None) -> "Config":
        """Builds a config from a nested dict on top of `base` (the defaults when None; `base`
        itself is not changed), refusing unknown sections and keys and values of the wrong
        type, naming `source` and the key."""
        cfg = Config() if base is None else base.copy()
        for section, values in d.items():
            target = getattr(cfg, section, None)
            if target is None or not isinstance(values, dict):
                raise ConfigError(f"{source}: unknown section [{section}] "
                                  f"(known: [model], [loss], [train])")
            known = {f.name: f for f in dataclasses.fields(target)}
            for key, value in values.items():
                if key not in known:
                    raise ConfigError(f"{source}: unknown key {section}.{key} "
                                      f"(known: {', '.join(sorted(known))})")
                default = getattr(target, key)
                setattr(target, key, _typed(value, default, f"{source}: {section}.{key}"))
        cfg.validate(source)
        return cfg

    def validate(self, source: str = "config") -> None:
        """Checks values that would fail later in a less clear way."""
        m = self.model
        if m.downsample < 2 or m.downsample & (m.downsample - 1):
            raise ConfigError(f"{source}: model.downsample = {m.downsample}, must be a power of two ≥ 2")
        if len(m.channels) != m.levels() + 1:
            raise ConfigError(f"{source}: model.channels has {len(m.channels)} entries; downsample "
                              f"{m.downsample} needs {m.levels() + 1} (one per level)")
        if len(m.blocks) != len(m.channels):
            raise ConfigError(f"{source}: model.blocks has {len(m.blocks)} entries, "
                              f"model.channels {len(m.channels)}; give one per level")
        if m.channels[-1] % m.heads:
            raise ConfigError(f"{source}: model.channels[-1] = {m.channels[-1]} does not split "
                              f"into model.heads = {m.heads}")
        if self.train.structure not in STRUCTURES:
            raise ConfigError(f"{source}: train.structure = {self.train.structure!r}, expected "
                              f"one of {', '.join(map(repr, STRUCTURES))}")
        if not 0.0 <= self.train.ema_decay < 1.0:
            raise ConfigError(f"{source}: train.ema_decay = {self.train.ema_decay}, expected 0 ≤ decay < 1")
        if m.finest_conv < 0:
            raise ConfigError(f"{source}: model.finest_conv = {m.finest_conv}, expected ≥ 0")
        if self.train.hold_out < 0:
            raise ConfigError(f"{source}: train.hold_out = {self.train.hold_out}, expected ≥ 0")
        if self.train.batch_size < 1 or self.train.steps < 0:
            raise ConfigError(f"{source}: train.batch_size must be ≥ 1 and train.steps ≥ 0")


#: Values of `train.structure`.
STRUCTURES = ("true", "siblings")


def _typed(value: Any, default: Any, where: str) -> Any:
    if isinstance(default, str):
        if not isinstance(value, str):
            raise ConfigError(f"{where} = {value!r}: expected a string")
        return value
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ConfigError(f"{where} = {value!r}: expected true or false")
        return value
    if isinstance(default, float) and isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    if isinstance(default, int) and isinstance(value, int) and not isinstance(value, bool):
        return value
    if isinstance(default, list) and isinstance(value, list) and all(
            isinstance(v, int) and not isinstance(v, bool) for v in value):
        return list(value)
    raise ConfigError(f"{where} = {value!r}: expected {type(default).__name__}")


def load_config(path: Optional[Path], base: Optional[Config] = None,
                base_name: Optional[str] = None) -> Config:
    """`base` (the defaults when None), with the keys the TOML file at `path` sets on top when
    it is given; a key the file leaves out keeps `base`'s value. `base_name` says what `base`
    is in error messages (a file's keys may clash with the base's, e.g. a `downsample` that
    needs another number of `channels`)."""
    if path is None:
        return Config() if base is None else base.copy()
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such config file") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path}: not valid TOML: {e}") from None
    source = str(path) if base_name is None else f"{path} (on top of {base_name})"
    return Config.from_dict(data, source, base)
