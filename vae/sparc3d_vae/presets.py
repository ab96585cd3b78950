"""The settings `train` starts from: the ones measured for the job's resolution.

`sparc3d_vae/configs/<N>.toml` holds the settings measured for jobs at N³ (each file says which
run of docs/VAE.md measured it), written on top of the base defaults of `config.py`
(`vae/vae.toml`). A new run takes, each layer on top of the one before:

1. the base defaults;
2. the file for the jobs' resolution (`for_jobs`): `<N>.toml` for jobs at N³. A resolution
   without a file of its own takes the largest measured resolution below it, or the smallest
   measured one when none is below: at 96³ the 64³ settings, at 32³ and 48³ the 64³ ones, at
   512³ the 256³ ones. The latent grid is N / `model.downsample`, and a file's `downsample` only
   grows with its resolution, so the rule never gives a job a coarser latent (relative to its
   grid) than the next measured resolution up would; a latent too coarse was the measured
   cause of the unseen error (docs/record/VAE-history.md, "Measured: the dev corpus"). Jobs of
   several resolutions take the file of the finest: its items are the largest, and its memory
   keys (`max_cells_per_batch`) are those their batches need;
3. with `train --init-from`, that run's `[model]` (its weights decide the network);
4. the keys that `--config FILE` sets.

A resumed run keeps the settings its checkpoint recorded, with `--config`'s keys on top
(`train`). `Settings` records the layers a run took (config.json's and the checkpoint's
`settings`) and says them in one line.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

from .config import Config, ConfigError, load_config

#: Where the measured settings live: package data, installed with the package.
CONFIG_DIR = Path(__file__).resolve().parent / "configs"
#: How messages and records name that folder, wherever the package is installed.
CONFIG_DIR_NAME = "sparc3d_vae/configs"


def measured() -> Dict[int, Path]:
    """The resolutions with measured settings and their files, smallest first."""
    found = {int(f.stem): f for f in CONFIG_DIR.glob("*.toml") if f.stem.isdigit()}
    if not found:
        raise ConfigError(f"{CONFIG_DIR}: no measured settings (<N>.toml) there; sparc3d-vae "
                          "was installed without its package data: reinstall it "
                          "(pip install ./vae)")
    return dict(sorted(found.items()))


def measured_for(resolution: int, resolutions: Sequence[int]) -> int:
    """The measured resolution whose settings a job at `resolution`³ takes (module doc): its
    own when measured, else the largest measured one below it, else the smallest measured."""
    below = [r for r in resolutions if r <= resolution]
    return max(below) if below else min(resolutions)


def _cubes(resolutions: Sequence[int]) -> str:
    return ", ".join(f"{r}³" for r in resolutions)


@dataclass
class Settings:
    """Where a run's settings came from, layer by layer (module doc)."""

    #: The measured resolution whose file the run took; None: the base defaults alone (jobs
    #: that record no resolution).
    preset: Optional[int]
    #: The resolutions of the jobs it was chosen for.
    job_resolutions: List[int]
    #: The `--init-from` checkpoint whose `[model]` the run kept.
    model_from: Optional[str] = None
    #: The `--config` files applied on top, in order (a resumed run's come last).
    configs: List[str] = field(default_factory=list)
    #: False for a checkpoint written before runs recorded their settings.
    recorded: bool = True

    @property
    def file(self) -> Optional[str]:
        """The preset's file as `sparc3d_vae/configs/<N>.toml`."""
        return None if self.preset is None else f"{CONFIG_DIR_NAME}/{self.preset}.toml"

    def reasons(self) -> List[str]:
        """Why this preset, when the jobs' resolution is not simply the preset's."""
        why = []
        if len(self.job_resolutions) > 1:
            why.append(f"the jobs are at {_cubes(self.job_resolutions)}: the finest decides")
        finest = max(self.job_resolutions, default=None)
        if self.preset is not None and finest is not None and finest != self.preset:
            rule = ("the largest measured resolution below it" if finest > self.preset
                    else "the smallest measured resolution")
            why.append(f"{finest}³ has no measured settings: {rule}")
        return why

    def base(self) -> str:
        """The settings before `--config`, in words."""
        if not self.recorded:
            text = "the checkpoint's settings"
        elif self.preset is None:
            text = "the base settings of vae/vae.toml (the jobs record no resolution)"
        else:
            text = f"settings for {self.preset}³ jobs ({'; '.join([self.file, *self.reasons()])})"
        if self.model_from is not None:
            text += f" with the [model] of --init-from {self.model_from}"
        return text

    def message(self, resumed: bool = False) -> str:
        """The line `train` prints: which settings it took and how to change them."""
        text = self.base()
        if resumed:
            text = (f"resuming with the run's settings: {text}" if self.recorded
                    else "resuming with the checkpoint's settings")
        if self.configs:
            return f"{text}, then {', '.join(self.configs)} on top"
        return f"{text}; --config FILE to override"

    def record(self) -> Dict[str, Any]:
        """What config.json and the checkpoint keep (read back by `from_record`)."""
        return {"preset": self.preset, "file": self.file, "reasons": self.reasons(),
                "job_resolutions": self.job_resolutions, "model_from": self.model_from,
                "configs": self.configs}

    @staticmethod
    def from_record(record: Optional[Dict[str, Any]]) -> "Settings":
        """The settings a checkpoint recorded (`recorded` False for one that records none)."""
        if not isinstance(record, dict):
            return Settings(None, [], recorded=False)
        return Settings(record.get("preset"), list(record.get("job_resolutions") or []),
                        record.get("model_from"), list(record.get("configs") or []))


def for_jobs(job_resolutions: Sequence[int]) -> Tuple[Config, Settings]:
    """The measured settings for jobs at `job_resolutions` (module doc), and their record."""
    resolutions = sorted(set(job_resolutions))
    if not resolutions:
        return Config(), Settings(None, [])
    files = measured()
    preset = measured_for(resolutions[-1], list(files))
    return load_config(files[preset]), Settings(preset, resolutions)
