"""Local attention on sparse voxels: each voxel attends to the active voxels of its 3×3×3
neighbourhood (itself included), never to the whole shape.

Sparc3D §3.5 puts "a lightweight local attention" at the coarsest level of the encoder; TRELLIS'
sparse VAE uses attention in fixed 3D windows (`attn_mode: swin`, window 8) for the same reason:
the cost stays linear in the number of voxels. Here the neighbourhood is the submanifold kernel
map the convolutions already built, so no second structure is needed; a learned bias per head
and kernel offset gives the attention its sense of direction (a relative position bias).
"""

from __future__ import annotations

import math

import torch
from torch import nn

from .sparse import SparseTensor


def neighbourhood_attention(x: SparseTensor, q: torch.Tensor, k: torch.Tensor, v: torch.Tensor,
                            bias: torch.Tensor) -> torch.Tensor:
    """Softmax attention of every voxel over its 3×3×3 active neighbours. q, k, v: [N, H, d];
    bias: [27, H] added to the logits of each kernel offset. Returns [N, H, d]."""
    nb = x.neighbours()  # [N, 27], N where the neighbour is absent
    n, h, d = q.shape
    pad = lambda t: torch.cat([t, t.new_zeros(1, h, d)])  # noqa: E731
    kn, vn = pad(k)[nb], pad(v)[nb]  # [N, 27, H, d]
    logits = (q[:, None] * kn).sum(-1).float() / math.sqrt(d) + bias.float()[None]
    logits = logits.masked_fill((nb == n)[..., None], -torch.inf)  # the centre is always there
    a = torch.softmax(logits, dim=1).to(v.dtype)
    return (a[..., None] * vn).sum(1)


class LocalAttention(nn.Module):
    """Multi-head neighbourhood self-attention on a sparse tensor's features, C → C."""

    def __init__(self, channels: int, heads: int):
        super().__init__()
        if channels % heads:
            raise ValueError(f"{channels} channels do not split into {heads} heads")
        self.heads = heads
        self.qkv = nn.Linear(channels, 3 * channels)
        self.proj = nn.Linear(channels, channels)
        self.bias = nn.Parameter(torch.zeros(27, heads))

    def forward(self, x: SparseTensor) -> torch.Tensor:
        n, c = x.feats.shape
        q, k, v = self.qkv(x.feats).view(n, 3, self.heads, c // self.heads).unbind(1)
        out = neighbourhood_attention(x, q, k, v, self.bias)
        return self.proj(out.reshape(n, c))
