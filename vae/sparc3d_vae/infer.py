"""`encode`, `decode`, `reconstruct`, `evaluate`: a trained VAE applied to jobs and latents.

The commands' code lives in modules by role, all re-exported here:

- `loaded`: a checkpoint ready to run (`Loaded`): model, device, cell budget, batches;
- `latents`: latent shards, written by `encode` and read back for `decode` (their columns
  there);
- `trellis2_latents`: latents in TRELLIS.2's structured-latent layout inside a `sparc3d export
  --format trellis2` folder (`encode --format trellis2`), read back for `decode`;
- `meshes`: decoded cubes to meshes through `sparc3d extract` (`decode`, `reconstruct`);
- `evaluation`: `evaluate`, with `sampling` (which items), `pieces` (the pieces' bar),
  `aggregate` (over the items) and `eval_report` (summary.md).
"""

from __future__ import annotations

from .evaluation import eval_samples, evaluate
from .latents import LATENT_SCHEMA, LATENT_SHARD_SIZE, LATENT_TENSORS, encode, read_latents
from .loaded import Loaded
from .meshes import decode, extract, reconstruct, reconstruct_items, reported_pieces, safe_name
from .pieces import nearby_pieces, pieces_stable, within_20pct
from .sampling import choose, sample_key

__all__ = ["LATENT_SCHEMA", "LATENT_SHARD_SIZE", "LATENT_TENSORS", "Loaded", "choose", "decode",
           "encode", "eval_samples", "evaluate", "extract", "nearby_pieces", "pieces_stable",
           "read_latents", "reconstruct", "reconstruct_items", "reported_pieces", "safe_name",
           "sample_key", "within_20pct"]
