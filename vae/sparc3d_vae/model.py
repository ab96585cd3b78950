"""Sparconv-VAE (Sparc3D §3.5): a variational autoencoder made only of sparse convolutions that
compresses the Sparcubes parameters on the active cells (φ at the 8 corners and, when the job
stored it, the deformation δ) into a sparse latent and decodes back to the same parameters.

- Encoder: an input projection, then per level residual blocks and a 2×2×2 stride-2 sparse
  convolution, down to the latent grid (resolution / `downsample`); at the coarsest level
  local attention blocks; heads for the mean and log-variance of a `latent_channels` latent.
- Decoder: mirrors it. Each self-pruning upsample block predicts which of the 8 children of
  every voxel are occupied, keeps those (the true children during training when teacher
  forcing is on), subdivides onto them and refines with residual blocks.
- Heads at full resolution, per cell and corner: the sign of φ (a logit), its magnitude |φ|
  (softplus, voxels) and δ (0.5·tanh, voxels: Sparcubes clamps δ below 0.45 voxel per axis,
  docs/ALGORITHM.md §5).

Design choices from peers: LayerNorm + SiLU residual blocks whose last convolution starts at
zero, and subdivision (each voxel → its 8 children) as the upsampling step, as in TRELLIS'
sparse VAE decoders (`SparseSubdivideBlock3d`); pruning by a predicted child occupancy as in
Direct3D-S2's sparse SDF VAE and Sparc3D's self-pruning blocks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import List, Optional

import torch
import torch.nn.functional as F
from torch import nn

from .attention import LocalAttention
from .config import ModelConfig
from .ops import DownConv3d, SubdivideConv3d, SubmConv3d
from .sparse import SparseTensor, expand_children

#: Values per cell the heads predict: 8 sign logits, 8 magnitudes, 8 × 3 δ.
HEAD_SIGN, HEAD_MAG, HEAD_DELTA = slice(0, 8), slice(8, 16), slice(16, 40)


def input_channels(cfg: ModelConfig) -> int:
    """Features per cell: φ at the 8 corners, plus δ at the 8 corners when used."""
    return 8 + (24 if cfg.deformation else 0)


class ResBlock(nn.Module):
    """x + conv(SiLU(LN(conv(SiLU(LN(x)))))), the last convolution initialised to zero so a new
    block starts as the identity (TRELLIS zero-initialises it the same way)."""

    def __init__(self, channels: int):
        super().__init__()
        self.norm1 = nn.LayerNorm(channels)
        self.conv1 = SubmConv3d(channels, channels)
        self.norm2 = nn.LayerNorm(channels)
        self.conv2 = SubmConv3d(channels, channels)
        nn.init.zeros_(self.conv2.weight)

    def forward(self, x: SparseTensor) -> SparseTensor:
        h = self.conv1(x.replace(F.silu(self.norm1(x.feats))))
        h = self.conv2(h.replace(F.silu(self.norm2(h.feats))))
        return x.replace(x.feats + h.feats)


class AttentionBlock(nn.Module):
    """Pre-norm transformer block with local (3×3×3 neighbourhood) attention and an MLP."""

    def __init__(self, channels: int, heads: int):
        super().__init__()
        self.norm1 = nn.LayerNorm(channels)
        self.attn = LocalAttention(channels, heads)
        self.norm2 = nn.LayerNorm(channels)
        self.mlp = nn.Sequential(nn.Linear(channels, 2 * channels), nn.SiLU(),
                                 nn.Linear(2 * channels, channels))
        nn.init.zeros_(self.attn.proj.weight)
        nn.init.zeros_(self.mlp[2].weight)

    def forward(self, x: SparseTensor) -> SparseTensor:
        f = x.feats + self.attn(x.replace(self.norm1(x.feats)))
        return x.replace(f + self.mlp(self.norm2(f)))


class FineConv(nn.Module):
    """x + W·SiLU(conv(SiLU(LN(x)))): one 3×3×3 submanifold convolution at full resolution,
    C → `width` channels (narrower than C to keep the costliest level cheap), projected back
    by W, which starts at zero. Every peer decoder convolves at full resolution (TRELLIS'
    sparse structured-latent decoders end in residual conv blocks at the output resolution);
    without it a cell's corner values are a function of its parent's feature alone."""

    def __init__(self, channels: int, width: int):
        super().__init__()
        self.norm = nn.LayerNorm(channels)
        self.conv = SubmConv3d(channels, width)
        self.out = nn.Linear(width, channels)
        nn.init.zeros_(self.out.weight)
        nn.init.zeros_(self.out.bias)

    def forward(self, x: SparseTensor) -> SparseTensor:
        h = self.conv(x.replace(F.silu(self.norm(x.feats))))
        return x.replace(x.feats + self.out(F.silu(h.feats)))


class Down(nn.Module):
    """LN → SiLU → 2×2×2 stride-2 sparse convolution, one level up."""

    def __init__(self, cin: int, cout: int):
        super().__init__()
        self.norm = nn.LayerNorm(cin)
        self.conv = DownConv3d(cin, cout)

    def forward(self, x: SparseTensor) -> SparseTensor:
        return self.conv(x.replace(F.silu(self.norm(x.feats))))


class Encoder(nn.Module):
    """Cells with corner features → (mean, logvar) on the latent grid, and the voxel structure
    of every level (full resolution first), which the loss and teacher forcing use."""

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        ch = cfg.channels
        # Pointwise MLPs at full resolution (no 3×3×3 convolution there by default, see
        # `ModelConfig.blocks`): cheap, and they give that level some depth.
        self.proj = nn.Sequential(nn.Linear(input_channels(cfg), ch[0]), nn.SiLU(),
                                  nn.Linear(ch[0], ch[0]))
        self.stages = nn.ModuleList(
            nn.Sequential(*[ResBlock(ch[l]) for _ in range(cfg.blocks[l])]) for l in range(cfg.levels()))
        self.downs = nn.ModuleList(Down(ch[l], ch[l + 1]) for l in range(cfg.levels()))
        self.bottom = nn.Sequential(*[ResBlock(ch[-1]) for _ in range(cfg.blocks[-1])],
                                    *[AttentionBlock(ch[-1], cfg.heads) for _ in range(cfg.attention_blocks)])
        self.norm = nn.LayerNorm(ch[-1])
        self.head = nn.Linear(ch[-1], 2 * cfg.latent_channels)

    def forward(self, x: SparseTensor):
        h = x.replace(self.proj(x.feats))
        structure = [h]
        for stage, down in zip(self.stages, self.downs):
            h = down(stage(h))
            structure.append(h)
        h = self.bottom(h)
        mean, logvar = self.head(self.norm(h.feats)).float().chunk(2, dim=1)
        return h.replace(mean), logvar.clamp(-30.0, 20.0), structure


class Up(nn.Module):
    """Self-pruning upsample block: child occupancy logits [N, 8] for every voxel, then
    LN → SiLU → subdivision onto the kept children, then residual blocks."""

    def __init__(self, cin: int, cout: int, blocks: int):
        super().__init__()
        self.occ_norm = nn.LayerNorm(cin)
        self.occ = nn.Linear(cin, 8)
        self.norm = nn.LayerNorm(cin)
        self.sub = SubdivideConv3d(cin, cout)
        self.blocks = nn.Sequential(*[ResBlock(cout) for _ in range(blocks)])

    def occupancy(self, x: SparseTensor) -> torch.Tensor:
        return self.occ(self.occ_norm(x.feats)).float()

    def forward(self, x: SparseTensor, child: SparseTensor) -> SparseTensor:
        return self.blocks(self.sub(x.replace(F.silu(self.norm(x.feats))), child))


@dataclass
class Decoded:
    """What the decoder returns: per level from the latent down, the voxels that predicted
    child occupancy and their logits; the full-resolution cells and their head outputs."""

    parents: List[SparseTensor]
    occ_logits: List[torch.Tensor]
    cells: SparseTensor
    sign_logits: torch.Tensor  # [N, 8]
    magnitude: torch.Tensor    # [N, 8], voxels
    delta: Optional[torch.Tensor]  # [N, 8, 3], voxels


class TooManyVoxels(RuntimeError):
    """The decoder predicted more voxels than allowed (an untrained or mismatched model)."""


class Decoder(nn.Module):
    """Latent → pruned sparse cells with φ (sign, magnitude) and δ per corner."""

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        ch = cfg.channels
        self.cfg = cfg
        self.proj = nn.Linear(cfg.latent_channels, ch[-1])
        self.bottom = nn.Sequential(*[ResBlock(ch[-1]) for _ in range(cfg.blocks[-1])],
                                    *[AttentionBlock(ch[-1], cfg.heads) for _ in range(cfg.attention_blocks)])
        self.ups = nn.ModuleList(Up(ch[l + 1], ch[l], cfg.blocks[l]) for l in reversed(range(cfg.levels())))
        self.fine = FineConv(ch[0], cfg.finest_conv) if cfg.finest_conv else None
        self.norm = nn.LayerNorm(ch[0])
        self.head = nn.Sequential(nn.Linear(ch[0], ch[0]), nn.SiLU(),
                                  nn.Linear(ch[0], 8 + 8 + (24 if cfg.deformation else 0)))

    def forward(self, z: SparseTensor, targets: Optional[List[SparseTensor]] = None,
                max_voxels: Optional[int] = None, siblings: bool = False) -> Decoded:
        """`targets`: the encoder's structure per level (teacher forcing), or None to keep the
        children predicted occupied (logit > 0). `max_voxels` bounds any predicted level.
        `siblings` (with `targets`): the last level holds every child of the true parents,
        not only the true cells (`train.structure = "siblings"`)."""
        h = self.bottom(z.replace(self.proj(z.feats)))
        parents, logits = [], []
        for i, up in enumerate(self.ups):
            level = h.level - 1
            occ = up.occupancy(h)
            parents.append(h)
            logits.append(occ)
            if targets is not None and not (siblings and level == 0):
                child = targets[level]
            else:
                keep = occ > 0 if targets is None else torch.ones_like(occ, dtype=torch.bool)
                coords = expand_children(h, keep)
                if max_voxels is not None and len(coords) > max_voxels:
                    raise TooManyVoxels(
                        f"the decoder predicted {len(coords)} voxels at level {level} "
                        f"(more than {max_voxels}); is the checkpoint trained for this data?")
                child = SparseTensor(coords, coords.new_zeros(len(coords), 0, dtype=torch.float32),
                                     level, h.batch_size)
            h = up(h, child)
        if self.fine is not None:
            h = self.fine(h)
        out = self.head(self.norm(h.feats)).float()
        delta = None
        if self.cfg.deformation:
            delta = 0.5 * torch.tanh(out[:, HEAD_DELTA]).view(-1, 8, 3)
        return Decoded(parents, logits, h, out[:, HEAD_SIGN], F.softplus(out[:, HEAD_MAG]), delta)


class SparconvVAE(nn.Module):
    """Encoder + reparameterisation + decoder."""

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        self.cfg = cfg
        self.encoder = Encoder(cfg)
        self.decoder = Decoder(cfg)

    def encode(self, x: SparseTensor):
        """(mean as a sparse tensor on the latent grid, logvar [M, C], structure per level)."""
        return self.encoder(x)

    def forward(self, x: SparseTensor, sample: bool = True, teacher_forcing: bool = True,
                siblings: bool = False):
        """Encodes, samples the latent (or takes the mean), decodes (see `Decoder.forward` for
        `siblings`). Returns (decoded, mean, logvar, structure)."""
        mean, logvar, structure = self.encoder(x)
        z = mean.feats
        if sample:
            z = z + torch.exp(0.5 * logvar) * torch.randn_like(z)
        dec = self.decoder(mean.replace(z), structure if teacher_forcing else None,
                           siblings=siblings)
        return dec, mean, logvar, structure
