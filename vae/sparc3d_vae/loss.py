"""The training loss (Sparc3D §3.5):

    L = λ_occ·L_occ + λ_sign·L_sign + λ_mag·L_mag + λ_δ·L_δ + λ_KL·KL

- L_occ: binary cross-entropy of every decoder voxel's 8 child-occupancy logits against the
  true structure one level down, averaged per level, then over the levels.
- L_sign: binary cross-entropy of the sign logits against "φ < 0" (inside), per cell corner.
- L_mag: mean squared error of the predicted |φ| (voxels) per cell corner.
- L_δ: mean squared error of δ (voxels) per cell corner and axis, when the job stored δ.
- KL: KL divergence of the latent posterior to N(0, I), averaged over latent elements.

The φ and δ terms are taken per decoded cell corner whose vertex is a vertex of a true cell
(its φ and δ are known). A decoded cell that is not a true cell (`train.structure =
"siblings"`, or the decoder's own structure) also has corners whose vertex is unknown: far
enough from the surface that Sparcubes stored nothing there. Their sign target is the sign of
the cell's known corners when those agree (a cell holding no surface should not grow one); they
have no magnitude or δ target. The λ defaults (`config.LossConfig`, `vae/vae.toml`) are justified in
docs/VAE.md.
"""

from __future__ import annotations

from typing import Dict, List, Tuple

import torch
import torch.nn.functional as F

from .config import LossConfig
from .model import Decoded
from .sparse import CHILD_OFFSETS, SparseTensor, hash_coords, lookup

#: The loss terms `vae_loss` returns, in the log's order.
LOSS_TERMS = ["loss", "occ", "sign", "mag", "delta", "kl"]


def child_targets(parents: SparseTensor, truth: SparseTensor) -> torch.Tensor:
    """float [N, 8]: 1 where the child (in `CHILD_OFFSETS` order) of each parent voxel is a
    voxel of `truth` (the true structure one level down)."""
    c = parents.coords.to(torch.int64)
    offs = torch.tensor(CHILD_OFFSETS, dtype=torch.int64, device=c.device)
    child = torch.cat([c[:, None, :1].expand(-1, 8, 1), (c[:, None, 1:] << 1) + offs[None]], dim=2)
    _, found = lookup(truth.keys, hash_coords(child.view(-1, 4)))
    return found.view(-1, 8).float()


def corner_targets(cells: SparseTensor, feats: torch.Tensor, decoded: SparseTensor):
    """Targets at the corners of the `decoded` cells from the true `cells` and their features
    (φ at the 8 corners, then δ [8 × 3] when present): (known bool [M, 8], φ [M, 8],
    δ [M, 8, 3] or None), read at each corner's grid vertex; known where that vertex is a
    corner of a true cell."""
    dev = cells.coords.device
    offs = torch.tensor(CHILD_OFFSETS, dtype=torch.int64, device=dev)

    def corner_keys(c: torch.Tensor) -> torch.Tensor:
        c = c.to(torch.int64)
        k = torch.cat([c[:, None, :1].expand(-1, 8, 1), c[:, None, 1:] + offs[None]], dim=2)
        return hash_coords(k.view(-1, 4))

    vkeys, inverse = torch.unique(corner_keys(cells.coords), sorted=True, return_inverse=True)
    vphi = feats.new_zeros(len(vkeys), dtype=torch.float32)
    vphi[inverse] = feats[:, :8].float().reshape(-1)
    idx, found = lookup(vkeys, corner_keys(decoded.coords))
    m = len(decoded.coords)
    known = found.view(m, 8)
    phi = torch.where(found, vphi[idx], torch.zeros_like(vphi[idx])).view(m, 8)
    delta = None
    if feats.shape[1] >= 32:
        vdelta = feats.new_zeros(len(vkeys), 3, dtype=torch.float32)
        vdelta[inverse] = feats[:, 8:32].float().reshape(-1, 3)
        delta = (vdelta[idx] * found[:, None]).view(m, 8, 3)
    return known, phi, delta


def vae_loss(dec: Decoded, logvar: torch.Tensor, mean: torch.Tensor, structure: List[SparseTensor],
             target_feats: torch.Tensor, lam: LossConfig) -> Tuple[torch.Tensor, Dict[str, float]]:
    """The weighted loss and its terms (floats, for the log). `target_feats` are the true
    input features of `structure[0]`'s cells: φ at the 8 corners, then δ [8 × 3] if present."""
    occ_terms = []
    for parents, logits in zip(dec.parents, dec.occ_logits):
        target = child_targets(parents, structure[parents.level - 1])
        occ_terms.append(F.binary_cross_entropy_with_logits(logits, target))
    occ = torch.stack(occ_terms).mean() if occ_terms else mean.new_zeros(())

    known, phi, true_delta = corner_targets(structure[0], target_feats, dec.cells)
    inside, outside = (phi < 0) & known, (phi >= 0) & known
    agree = inside.any(1) ^ outside.any(1)  # known corners, all on one side
    sign_mask = known | agree[:, None]
    sign_target = torch.where(known, phi < 0, inside.any(1, keepdim=True).expand_as(known))
    zero = occ.new_zeros(())
    sign = F.binary_cross_entropy_with_logits(dec.sign_logits[sign_mask], sign_target[sign_mask].float()) \
        if bool(sign_mask.any()) else zero
    mag = F.mse_loss(dec.magnitude[known], phi[known].abs()) if bool(known.any()) else zero
    delta = zero
    if dec.delta is not None and bool(known.any()):
        delta = F.mse_loss(dec.delta[known], true_delta[known])
    m = mean.feats.float()
    kl = 0.5 * (m.pow(2) + logvar.exp() - 1.0 - logvar).mean()
    total = lam.occ * occ + lam.sign * sign + lam.mag * mag + lam.delta * delta + lam.kl * kl
    terms = {k: float(v.detach()) for k, v in
             (("loss", total), ("occ", occ), ("sign", sign), ("mag", mag), ("delta", delta), ("kl", kl))}
    return total, terms
