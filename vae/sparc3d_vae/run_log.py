"""What a training run shows and keeps as it goes: the progress line on stderr (`Progress`) and,
on rank 0, the run folder's `config.json`, `loss.csv` and TensorBoard scalars (`RunLog`)."""

from __future__ import annotations

import csv
import json
import sys
import time
from pathlib import Path
from typing import Dict, Optional

from . import presets
from .config import Config
from .loss import LOSS_TERMS

#: The columns of loss.csv.
LOG_FIELDS = ["step", *LOSS_TERMS, "lr", "cells", "seconds"]


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


class RunLog:
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
