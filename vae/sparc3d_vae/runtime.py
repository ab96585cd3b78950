"""What every command shares: the device, the seed, checkpoints, and running the `sparc3d`
binary (its `extract`, `eval` commands)."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import random
import shutil
import subprocess
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import numpy as np
import torch

from . import __version__
from .config import Config, ConfigError
from .model import SparconvVAE

CHECKPOINT_FORMAT = "sparc3d-vae-checkpoint"
CHECKPOINT_VERSION = 1
CHECKPOINT_NAME = "checkpoint.pt"


class UsageError(RuntimeError):
    """Something the user asked for that cannot be done; the message says what and why."""


def pick_device(name: str, index: Optional[int] = None) -> torch.device:
    """`auto`: CUDA when torch sees a GPU, else CPU. `cuda` without a usable GPU is refused.
    `index`: the GPU of this process when several train together (torchrun's LOCAL_RANK)."""
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    if name == "cuda" and index is not None and torch.cuda.is_available():
        if index >= torch.cuda.device_count():
            raise UsageError(f"LOCAL_RANK={index}, but torch sees {torch.cuda.device_count()} "
                             "CUDA device(s): start at most that many processes per machine")
        torch.cuda.set_device(index)
        return torch.device("cuda", index)
    if name == "cuda":
        if not torch.cuda.is_available():
            built = torch.version.cuda
            why = f"torch {torch.__version__} was built without CUDA" if not built else \
                "torch sees no CUDA device (driver, CUDA_VISIBLE_DEVICES?)"
            raise UsageError(f"--device cuda: no CUDA device available ({why}); use --device cpu")
        return torch.device("cuda")
    if name == "cpu":
        return torch.device("cpu")
    raise UsageError(f"--device {name!r}: expected cpu, cuda or auto")


#: What PyTorch raises when the GPU runs out of memory (torch.OutOfMemoryError since 2.5).
OutOfMemory = getattr(torch, "OutOfMemoryError", None) or torch.cuda.OutOfMemoryError


@contextlib.contextmanager
def memory_guard(what: str, cells: int, limit: int, device: torch.device,
                 setting: str = "train.max_cells_per_batch", where: str = " in --config"):
    """Turns a GPU out-of-memory error inside the block into a UsageError naming the batch
    (`what`, its `cells`) and the budget to lower (`setting`, set `where`), instead of a stack
    trace."""
    try:
        yield
    except OutOfMemory:
        if device.type == "cuda":
            torch.cuda.empty_cache()
        raise UsageError(f"{device} ran out of memory on {what} ({cells} cells; "
                         f"{setting} = {limit}): lower {setting} "
                         f"(e.g. to {max(1, min(cells, limit) // 2)}){where}") from None


def seed_everything(seed: int) -> None:
    """Seeds Python, numpy and torch (CPU and CUDA)."""
    random.seed(seed)
    np.random.seed(seed % (1 << 32))
    torch.manual_seed(seed)


def autocast(device: torch.device):
    """bf16 autocast on CUDA; nothing on CPU (CPU runs in float32, deterministically)."""
    return torch.autocast("cuda", dtype=torch.bfloat16, enabled=device.type == "cuda")


def digest_ids(ids: Sequence[str]) -> str:
    """A short digest of the item ids a model was trained on (to notice other data on resume)."""
    h = hashlib.sha256()
    for i in ids:
        h.update(i.encode())
        h.update(b"\0")
    return h.hexdigest()[:16]


def checkpoint_path(path: Path) -> Path:
    """A checkpoint file, or the run folder holding `checkpoint.pt`."""
    path = Path(path)
    return path / CHECKPOINT_NAME if path.is_dir() else path


def save_checkpoint(path: Path, state: Dict[str, Any]) -> None:
    """Writes a checkpoint atomically (temporary file, then rename), so a kill never leaves a
    half-written one in place."""
    tmp = path.with_name(path.name + ".tmp")
    torch.save({"format": CHECKPOINT_FORMAT, "version": CHECKPOINT_VERSION,
                "tool_version": __version__, **state}, tmp)
    os.replace(tmp, path)


def load_checkpoint(path: Path) -> Dict[str, Any]:
    """Reads a checkpoint written by `save_checkpoint`; refuses other files clearly."""
    path = checkpoint_path(path)
    if not path.is_file():
        raise UsageError(f"{path}: no checkpoint there (train writes RUN/{CHECKPOINT_NAME})")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # a truncated file or another format: say which file
        raise UsageError(f"{path}: not a readable sparc3d-vae checkpoint ({e})") from None
    if not isinstance(state, dict) or state.get("format") != CHECKPOINT_FORMAT:
        raise UsageError(f"{path}: not a sparc3d-vae checkpoint")
    if state.get("version") != CHECKPOINT_VERSION:
        raise UsageError(f"{path}: checkpoint format version {state.get('version')}, this "
                         f"sparc3d-vae reads version {CHECKPOINT_VERSION}")
    return state


def model_from_checkpoint(state: Dict[str, Any], device: torch.device, source: str):
    """(config, model in eval mode) from a loaded checkpoint: its EMA weights when it has them."""
    try:
        cfg = Config.from_dict(state["config"], f"{source} (its config)")
    except ConfigError as e:
        raise UsageError(str(e)) from None
    model = SparconvVAE(cfg.model)
    # The moving average of the weights when the run kept one (train.ema_decay).
    load_weights(model, state.get("ema") or state["model"], source)
    return cfg, model.to(device).eval()


def load_weights(model: torch.nn.Module, weights: Dict[str, Any], source: str) -> None:
    """Loads a checkpoint's weights into a model built from the checkpoint's own config;
    weights that do not fit are a clear error naming `source`, not a stack trace."""
    try:
        model.load_state_dict(weights)
    except RuntimeError as e:
        first = str(e).splitlines()[0] if str(e) else "mismatch"
        raise UsageError(f"{source}: its weights do not fit its own config ({first}); written "
                         "by another version of sparc3d-vae?") from None


def config_diff(a: Dict[str, Any], b: Dict[str, Any], prefix: str = "") -> List[str]:
    """Keys (dotted) whose values differ between two nested dicts."""
    out = []
    for k in sorted(set(a) | set(b)):
        va, vb = a.get(k), b.get(k)
        if isinstance(va, dict) and isinstance(vb, dict):
            out += config_diff(va, vb, f"{prefix}{k}.")
        elif va != vb:
            out.append(f"{prefix}{k}: {va!r} → {vb!r}")
    return out


# --- The sparc3d binary ---------------------------------------------------------------------------

def find_sparc3d(explicit: Optional[str] = None) -> str:
    """The `sparc3d` binary: `--sparc3d PATH`, else `SPARC3D_BIN`, else `sparc3d` on PATH."""
    for candidate in (explicit, os.environ.get("SPARC3D_BIN")):
        if candidate:
            if not (Path(candidate).is_file() and os.access(candidate, os.X_OK)):
                raise UsageError(f"{candidate}: not an executable sparc3d binary")
            return candidate
    found = shutil.which("sparc3d")
    if not found:
        raise UsageError("the sparc3d binary is not on PATH (install it with `cargo install "
                         "--locked --path pipeline`, or pass --sparc3d PATH / set SPARC3D_BIN)")
    return found


def run_sparc3d(binary: str, *args: Any) -> Dict[str, Any]:
    """Runs `sparc3d ARGS --json` and returns its JSON summary; a failure is a UsageError with
    the command and its message."""
    cmd = [binary, *map(str, args), "--json"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        msg = (r.stderr.strip() or r.stdout.strip()).splitlines()
        raise UsageError(f"sparc3d {' '.join(map(str, args))}: {msg[-1] if msg else 'failed'}")
    try:
        return json.loads(r.stdout.strip().splitlines()[-1])
    except (json.JSONDecodeError, IndexError):
        raise UsageError(f"sparc3d {' '.join(map(str, args))}: no JSON summary in its output") from None
