"""The training loss (Sparc3D §3.5):

    L = λ_occ·L_occ + λ_sign·L_sign + λ_mag·L_mag + λ_δ·L_δ + λ_KL·KL

- L_occ: binary cross-entropy of every decoder voxel's 8 child-occupancy logits against the
  true structure one level down, averaged per level, then over the levels.
- L_sign: binary cross-entropy of the sign logits against "φ < 0" (inside), per cell corner.
- L_mag: mean squared error of the predicted |φ| (voxels) per cell corner.
- L_δ: mean squared error of δ (voxels) per cell corner and axis, when the job stored δ.
- KL: KL divergence of the latent posterior to N(0, I), averaged over latent elements.

The φ and δ terms are taken over the decoded cells that are true cells (all of them under
teacher forcing). The λ defaults (`config.LossConfig`, `vae/vae.toml`) are justified in
docs/VAE.md.
"""

from __future__ import annotations

from typing import Dict, List, Tuple

import torch
import torch.nn.functional as F

from .config import LossConfig
from .model import Decoded
from .sparse import CHILD_OFFSETS, SparseTensor, hash_coords, lookup


def child_targets(parents: SparseTensor, truth: SparseTensor) -> torch.Tensor:
    """float [N, 8]: 1 where the child (in `CHILD_OFFSETS` order) of each parent voxel is a
    voxel of `truth` (the true structure one level down)."""
    c = parents.coords.to(torch.int64)
    offs = torch.tensor(CHILD_OFFSETS, dtype=torch.int64, device=c.device)
    child = torch.cat([c[:, None, :1].expand(-1, 8, 1), (c[:, None, 1:] << 1) + offs[None]], dim=2)
    _, found = lookup(truth.keys, hash_coords(child.view(-1, 4)))
    return found.view(-1, 8).float()


def vae_loss(dec: Decoded, logvar: torch.Tensor, mean: torch.Tensor, structure: List[SparseTensor],
             target_feats: torch.Tensor, lam: LossConfig) -> Tuple[torch.Tensor, Dict[str, float]]:
    """The weighted loss and its terms (floats, for the log). `target_feats` are the true
    input features of `structure[0]`'s cells: φ at the 8 corners, then δ [8 × 3] if present."""
    occ_terms = []
    for parents, logits in zip(dec.parents, dec.occ_logits):
        target = child_targets(parents, structure[parents.level - 1])
        occ_terms.append(F.binary_cross_entropy_with_logits(logits, target))
    occ = torch.stack(occ_terms).mean() if occ_terms else mean.new_zeros(())

    idx, found = lookup(structure[0].keys, dec.cells.keys)
    rows = idx[found]
    phi = target_feats[rows, :8].float()
    sign = F.binary_cross_entropy_with_logits(dec.sign_logits[found], (phi < 0).float()) \
        if len(rows) else occ.new_zeros(())
    mag = F.mse_loss(dec.magnitude[found], phi.abs()) if len(rows) else occ.new_zeros(())
    delta = occ.new_zeros(())
    if dec.delta is not None and len(rows):
        true_delta = target_feats[rows, 8:32].float().view(-1, 8, 3)
        delta = F.mse_loss(dec.delta[found], true_delta)
    m = mean.feats.float()
    kl = 0.5 * (m.pow(2) + logvar.exp() - 1.0 - logvar).mean()
    total = lam.occ * occ + lam.sign * sign + lam.mag * mag + lam.delta * delta + lam.kl * kl
    terms = {k: float(v.detach()) for k, v in
             (("loss", total), ("occ", occ), ("sign", sign), ("mag", mag), ("delta", delta), ("kl", kl))}
    return total, terms
