"""A trained checkpoint ready to run (`Loaded`): its model on a device, the cells one forward
pass may hold, the jobs' samples checked against what it was trained on, and the model's
encoding and decoding of one batch. `latents`, `meshes` and `evaluation` build on it.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Dict, Iterator, List, Optional, Sequence

import numpy as np
import torch

from .data import Cubes, DataError, Sample, Samples, corners_to_cubes, job_info, make_batch
from .runtime import (UsageError, autocast, checkpoint_path, load_checkpoint, memory_guard,
                      model_from_checkpoint, pick_device)
from .sparse import SparseTensor


class Loaded:
    """A checkpoint ready to run: config, model, device, and its limits."""

    def __init__(self, ckpt: Path, device_name: str, max_cells: Optional[int] = None):
        self.path = checkpoint_path(ckpt)
        state = load_checkpoint(self.path)
        self.device = pick_device(device_name)
        self.cfg, self.model = model_from_checkpoint(state, self.device, str(self.path))
        if max_cells is not None and max_cells < 1:
            raise UsageError(f"--max-cells {max_cells}: must be a positive number of cells")
        # Cells per forward pass: the training budget unless asked (inference keeps no
        # gradients, so a model runs on grids finer than it trained on with a larger one).
        self.max_cells = max_cells or self.cfg.train.max_cells_per_batch
        self.budget_note = ("--max-cells" if max_cells else
                            f"train.max_cells_per_batch of {self.path}; raise it with --max-cells")
        self.digest = hashlib.sha256(self.path.read_bytes()).hexdigest()[:16]
        if self.cfg.train.threads > 0 and self.device.type == "cpu":
            torch.set_num_threads(self.cfg.train.threads)

    def check_data(self, deformation: bool, source: str) -> None:
        """Refuses data whose kind (with or without δ) differs from what the model was trained on."""
        if deformation != self.cfg.model.deformation:
            raise UsageError(
                f"{source}: the data {'stores' if deformation else 'has no'} deformation, but "
                f"the checkpoint {self.path} was trained {'with' if self.cfg.model.deformation else 'without'} it")

    def load_samples(self, data: Sequence[str]) -> Samples:
        """The samples of the jobs (or shard files) `data`, read on demand; refused when their
        kind differs from the model's (`check_data`)."""
        info = job_info(data)
        self.check_data(info.deformation, ", ".join(data))
        return Samples(info, cache=False)

    def too_large(self, s: Sample) -> Optional[str]:
        """Why an item cannot go through one forward pass, or None when it fits."""
        if len(s.cells) <= self.max_cells:
            return None
        return (f"item {s.id!r}: {len(s.cells)} cells, more than the {self.max_cells} cells "
                f"per forward pass ({self.budget_note})")

    def batches(self, samples: Sequence[Sample]) -> Iterator[List[Sample]]:
        """Samples grouped so that no group holds more than `max_cells` cells; an item larger
        than that alone is refused, naming it."""
        limit = self.max_cells
        group: List[Sample] = []
        cells = 0
        for s in samples:
            why = self.too_large(s)
            if why:
                raise DataError(why)
            if group and (cells + len(s.cells) > limit or len(group) >= self.cfg.train.batch_size):
                yield group
                group, cells = [], 0
            group.append(s)
            cells += len(s.cells)
        if group:
            yield group

    @torch.no_grad()
    def encode(self, samples: Sequence[Sample]) -> List[Dict[str, np.ndarray]]:
        """Latent mean / logvar of each sample: coords int32 [n, 3], mean, logvar float32 [n, C]."""
        x = make_batch(samples, self.device)
        what = f"encoding {', '.join(repr(s.id) for s in samples)}"
        with memory_guard(what, len(x.coords), self.max_cells, self.device, "--max-cells", ""), \
                autocast(self.device):
            mean, logvar, _ = self.model.encode(x)
        out = []
        for b in range(len(samples)):
            rows = mean.coords[:, 0] == b
            out.append({"coords": mean.coords[rows, 1:].cpu().numpy().astype(np.int32),
                        "mean": mean.feats[rows].float().cpu().numpy(),
                        "logvar": logvar[rows].float().cpu().numpy()})
        return out

    @torch.no_grad()
    def decode(self, latents: Sequence[Dict[str, np.ndarray]]) -> List[Cubes]:
        """Sparse cubes decoded from latents (the mean), pruned by the predicted occupancy."""
        coords = np.concatenate([np.concatenate([np.full((len(l["coords"]), 1), b, np.int32),
                                                 l["coords"].astype(np.int32)], 1)
                                 for b, l in enumerate(latents)])
        feats = np.concatenate([l["mean"].astype(np.float32) for l in latents])
        z = SparseTensor.build(torch.from_numpy(coords).to(self.device),
                               torch.from_numpy(feats).to(self.device),
                               level=self.cfg.model.levels(), batch_size=len(latents))
        limit = self.max_cells
        what = f"decoding {len(latents)} latent(s), at most 8× the budget"
        with memory_guard(what, 8 * limit, limit, self.device, "--max-cells", ""), autocast(self.device):
            dec = self.model.decoder(z, None, max_voxels=limit * 8)
        return corners_to_cubes(dec.cells, dec.sign_logits, dec.magnitude, dec.delta)
