"""The three sparse convolutions of the VAE, as gather → matmul → scatter-add over kernel maps
(`sparse.py`), in plain PyTorch on CPU and CUDA alike:

- `SubmConv3d`: submanifold 3×3×3 convolution, the output voxels are the input voxels; equals
  `F.conv3d(dense, w, padding=1)` read at the active voxels when the dense grid is zero elsewhere.
- `DownConv3d`: 2×2×2 convolution with stride 2 onto the parents of the active voxels; equals
  `F.conv3d(dense, w, stride=2)` read at those parents.
- `SubdivideConv3d`: each voxel → its children (2×2×2 transposed convolution, stride 2), read
  only at the children kept; equals `F.conv_transpose3d(dense, w, stride=2)` there.

Weights are stored as [K, C_in, C_out] (K kernel offsets in the order of `sparse.SUBM_OFFSETS`
/ `sparse.CHILD_OFFSETS`). `vae/tests/test_sparse_ops.py` checks values and gradients against
the dense operators.

The submanifold convolution is a `torch.autograd.Function` that saves only its input and the
kernel map: autograd through 27 gathers would keep every gathered copy (about 10× the input on
a surface) alive until the backward pass. Under CUDA autocast it computes in the autocast dtype.
"""

from __future__ import annotations

import math
import torch
from torch import nn

from .sparse import CENTRE, SparseTensor, children_of, parent_structure


def _compute_dtype(x: torch.Tensor) -> torch.dtype:
    dev = x.device.type
    if dev in ("cuda", "cpu") and torch.is_autocast_enabled(dev):
        return torch.get_autocast_dtype(dev)
    return x.dtype


#: Elements of gathered neighbour features one chunk of rows may hold (bounds the temporary
#: memory of a convolution: 2^24 floats = 64 MiB in float32).
CHUNK_ELEMENTS = 1 << 24
#: The same on CUDA: 2^27 elements (256 MiB in bf16), so that a 256³ batch of about a million
#: cells at 64 channels is a dozen large matmuls per convolution, not hundreds of small
#: launches from Python.
CHUNK_ELEMENTS_CUDA = 1 << 27


def _chunks(n: int, width: int, device: torch.device = None):
    budget = CHUNK_ELEMENTS_CUDA if device is not None and device.type == "cuda" else CHUNK_ELEMENTS
    step = max(1, budget // max(width, 1))
    for lo in range(0, n, step):
        yield lo, min(n, lo + step)


class _SubmConvFn(torch.autograd.Function):
    """out[r] = Σ_k in[nb[r, k]] · W[k] (see `subm_conv3d`): per chunk of output rows, gather
    the 27 neighbours' features, one matmul; backward: one matmul and a scatter-add into the
    neighbours' rows, the weight gradient from the same gathered features (gathered again,
    so only the input is saved)."""

    @staticmethod
    def forward(ctx, feats: torch.Tensor, weight: torch.Tensor, nb: torch.Tensor) -> torch.Tensor:
        dt = _compute_dtype(feats)
        n, cin = feats.shape
        k, _, cout = weight.shape
        with torch.autocast(feats.device.type, enabled=False):
            f = torch.cat([feats.to(dt), feats.new_zeros(1, cin, dtype=dt)])  # row n: padding
            w = weight.to(dt).reshape(k * cin, cout)
            out = f.new_empty(n, cout)
            for lo, hi in _chunks(n, k * cin, feats.device):
                out[lo:hi] = f[nb[lo:hi]].reshape(hi - lo, k * cin) @ w
        ctx.save_for_backward(f, w, nb)
        ctx.dtypes = (feats.dtype, weight.dtype)
        ctx.shape = (k, cin, cout)
        return out

    @staticmethod
    def backward(ctx, grad_out: torch.Tensor):
        f, w, nb = ctx.saved_tensors
        k, cin, cout = ctx.shape
        n = len(nb)
        g = grad_out.to(f.dtype)
        grad_f = torch.zeros_like(f) if ctx.needs_input_grad[0] else None
        grad_w = torch.zeros_like(w) if ctx.needs_input_grad[1] else None
        with torch.autocast(g.device.type, enabled=False):
            for lo, hi in _chunks(n, k * cin, g.device):
                gc = g[lo:hi]
                if grad_f is not None:
                    grad_f.index_add_(0, nb[lo:hi].reshape(-1), (gc @ w.t()).reshape(-1, cin))
                if grad_w is not None:
                    grad_w += f[nb[lo:hi]].reshape(hi - lo, k * cin).t() @ gc
        if grad_f is not None:
            grad_f = grad_f[:n].to(ctx.dtypes[0])
        if grad_w is not None:
            grad_w = grad_w.reshape(k, cin, cout).to(ctx.dtypes[1])
        return grad_f, grad_w, None


def subm_conv3d(x: SparseTensor, weight: torch.Tensor, bias: torch.Tensor = None) -> SparseTensor:
    """Submanifold 3×3×3 convolution of `x` with `weight` [27, C_in, C_out] (+ `bias`)."""
    out = _SubmConvFn.apply(x.feats, weight, x.neighbours())
    if bias is not None:
        out = out + bias.to(out.dtype)
    return x.replace(out)


def down_conv3d(x: SparseTensor, weight: torch.Tensor, bias: torch.Tensor = None) -> SparseTensor:
    """2×2×2 stride-2 convolution of `x` with `weight` [8, C_in, C_out] onto the parent voxels
    (one level up): each parent gathers its 8 children's features (zero for absent ones), one
    matmul; autograd scatter-adds the gradient back."""
    parents, parent_row, offset = parent_structure(x)
    n, cin = x.feats.shape
    table = torch.full((len(parents), 8), n, dtype=torch.int64, device=x.feats.device)
    table[parent_row, offset] = torch.arange(n, device=x.feats.device)
    f = torch.cat([x.feats, x.feats.new_zeros(1, cin)])
    out = f[table].reshape(len(parents), 8 * cin) @ weight.reshape(8 * cin, -1)
    if bias is not None:
        out = out + bias.to(out.dtype)
    cache = {"keys": x.cache["parent_keys"]}
    return SparseTensor(parents, out, x.level + 1, x.batch_size, cache)


def subdivide_conv3d(x: SparseTensor, child: SparseTensor, weight: torch.Tensor,
                     bias: torch.Tensor = None) -> SparseTensor:
    """Each voxel of `x` → its children that are in `child` (one level down; its features are
    ignored, its coordinates and cache are used): out[c] = x[parent(c)] · W[offset(c)] with
    `weight` [8, C_in, C_out] (+ `bias`). One matmul gives every parent's 8 candidate children,
    a gather keeps the children that exist."""
    parent_row, offset = children_of(x, child.coords)
    cin, cout = weight.shape[1], weight.shape[2]
    every = x.feats @ weight.permute(1, 0, 2).reshape(cin, 8 * cout)  # [P, 8·C_out]
    out = every.reshape(-1, cout)[parent_row * 8 + offset]
    if bias is not None:
        out = out + bias.to(out.dtype)
    return child.replace(out)


def _init_weight(k: int, cin: int, cout: int) -> nn.Parameter:
    # The default of torch.nn.Conv3d (Kaiming-uniform with a = √5): bound 1/√fan_in.
    bound = 1.0 / math.sqrt(k * cin)
    return nn.Parameter(torch.empty(k, cin, cout).uniform_(-bound, bound))


class _SparseConv(nn.Module):
    """Weights [K, C_in, C_out] (initialised as torch.nn.Conv3d's) and an optional bias."""

    def __init__(self, kernel: int, cin: int, cout: int, bias: bool):
        super().__init__()
        self.weight = _init_weight(kernel, cin, cout)
        self.bias = nn.Parameter(torch.zeros(cout)) if bias else None


class SubmConv3d(_SparseConv):
    """Submanifold 3×3×3 sparse convolution (outputs at the input voxels)."""

    def __init__(self, cin: int, cout: int, bias: bool = True):
        super().__init__(27, cin, cout, bias)

    def forward(self, x: SparseTensor) -> SparseTensor:
        return subm_conv3d(x, self.weight, self.bias)


class DownConv3d(_SparseConv):
    """2×2×2 stride-2 sparse convolution: the voxels one level up, C_in → C_out."""

    def __init__(self, cin: int, cout: int, bias: bool = True):
        super().__init__(8, cin, cout, bias)

    def forward(self, x: SparseTensor) -> SparseTensor:
        return down_conv3d(x, self.weight, self.bias)


class SubdivideConv3d(_SparseConv):
    """Subdivision upsampling: every voxel → its kept children, a 2×2×2 stride-2 transposed
    convolution read at those children."""

    def __init__(self, cin: int, cout: int, bias: bool = True):
        super().__init__(8, cin, cout, bias)

    def forward(self, x: SparseTensor, child: SparseTensor) -> SparseTensor:
        return subdivide_conv3d(x, child, self.weight, self.bias)
