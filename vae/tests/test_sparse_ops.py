"""Each sparse op equals its dense PyTorch operator on a grid that is zero outside the active
voxels, read at the active voxels: values, input gradients and weight gradients, on batches of
several differently shaped voxel sets (a shell, a blob, scattered voxels)."""

import pytest
import torch
import torch.nn.functional as F

from sparc3d_vae.ops import down_conv3d, subdivide_conv3d, subm_conv3d
from sparc3d_vae.sparse import SparseTensor, expand_children, hash_coords, unhash

D = 12  # grid side (even, so stride 2 tiles it)


def shapes(seed):
    """Three voxel sets of different kinds in a D³ grid, as int32 [N, 4] rows (batch, x, y, z)."""
    g = torch.Generator().manual_seed(seed)
    ax = torch.arange(D)
    x, y, z = torch.meshgrid(ax, ax, ax, indexing="ij")
    r = ((x - 5.5) ** 2 + (y - 6.0) ** 2 + (z - 4.5) ** 2).sqrt()
    shell = (r > 3.0) & (r < 4.2)                       # a spherical shell (surface-like)
    blob = ((x - 3) ** 2 / 4 + (y - 8) ** 2 / 9 + (z - 7) ** 2 / 2) < 2.5  # a solid ellipsoid
    scattered = torch.rand(D, D, D, generator=g) < 0.15  # random, mostly isolated voxels
    rows = []
    for b, m in enumerate([shell, blob, scattered]):
        idx = torch.nonzero(m)
        rows.append(torch.cat([torch.full((len(idx), 1), b), idx], dim=1))
    return torch.cat(rows).to(torch.int32)


def dense(coords, feats, batch=3, side=D):
    """Scatters sparse rows into a zero dense grid [B, C, side, side, side]."""
    out = torch.zeros(batch, feats.shape[1], side, side, side, dtype=feats.dtype)
    c = coords.long()
    out[c[:, 0], :, c[:, 1], c[:, 2], c[:, 3]] = feats
    return out


def gather(grid, coords):
    c = coords.long()
    return grid[c[:, 0], :, c[:, 1], c[:, 2], c[:, 3]]


def assert_same_gradients(out, ref, inputs):
    """Gradients of Σ out·g and Σ ref·g (one random g) with respect to `inputs` are equal."""
    g = torch.randn_like(ref)
    grads = torch.autograd.grad((out * g).sum(), inputs, retain_graph=True)
    grads_ref = torch.autograd.grad((ref * g).sum(), inputs)
    for a, b in zip(grads, grads_ref):
        torch.testing.assert_close(a, b)


@pytest.mark.parametrize("seed", [0, 1])
def test_submanifold_conv_equals_dense_conv3d(seed):
    torch.manual_seed(seed)
    coords = shapes(seed)
    # Rows in a shuffled order: `build` sorts them.
    perm = torch.randperm(len(coords))
    coords = coords[perm]
    feats = torch.randn(len(coords), 3, dtype=torch.float64, requires_grad=True)
    w_dense = torch.randn(4, 3, 3, 3, 3, dtype=torch.float64, requires_grad=True)
    bias = torch.randn(4, dtype=torch.float64, requires_grad=True)
    x = SparseTensor.build(coords, feats)
    # [C_out, C_in, 3, 3, 3] → [27, C_in, C_out] in the order of sparse.SUBM_OFFSETS.
    w_sparse = w_dense.permute(2, 3, 4, 1, 0).reshape(27, 3, 4)
    y = subm_conv3d(x, w_sparse, bias)
    ref = gather(F.conv3d(dense(x.coords, x.feats), w_dense, bias, padding=1), x.coords)
    torch.testing.assert_close(y.feats, ref)
    assert torch.equal(y.coords, x.coords)

    assert_same_gradients(y.feats, ref, (feats, w_dense, bias))


def test_submanifold_conv_gradcheck():
    coords = shapes(3)[::25]
    feats = torch.randn(len(coords), 2, dtype=torch.float64, requires_grad=True)
    w = torch.randn(27, 2, 3, dtype=torch.float64, requires_grad=True)
    x = SparseTensor.build(coords, feats.detach())
    nb = x.neighbours()  # built once; gradcheck reuses it

    def f(feats, w):
        return subm_conv3d(x.replace(feats), w).feats

    assert nb is x.neighbours()
    torch.autograd.gradcheck(f, (feats[torch.argsort(hash_coords(coords))].detach().requires_grad_(), w))


def test_down_conv_equals_strided_dense_conv3d():
    torch.manual_seed(4)
    coords = shapes(4)
    feats = torch.randn(len(coords), 3, dtype=torch.float64, requires_grad=True)
    w_dense = torch.randn(5, 3, 2, 2, 2, dtype=torch.float64, requires_grad=True)
    bias = torch.randn(5, dtype=torch.float64, requires_grad=True)
    x = SparseTensor.build(coords, feats)
    y = down_conv3d(x, w_dense.permute(2, 3, 4, 1, 0).reshape(8, 3, 5), bias)
    assert y.level == 1
    # The parents are exactly the coarse voxels with an active child (nonzero lists them in
    # (batch, x, y, z) order, the order of the keys).
    occupied = F.max_pool3d(dense(x.coords, torch.ones(len(coords), 1, dtype=torch.float64)), 2)
    assert torch.equal(y.coords, torch.nonzero(occupied[:, 0] > 0).to(torch.int32))
    ref = gather(F.conv3d(dense(x.coords, x.feats), w_dense, bias, stride=2), y.coords)
    torch.testing.assert_close(y.feats, ref)
    assert_same_gradients(y.feats, ref, (feats, w_dense, bias))


def test_subdivision_equals_transposed_dense_conv_at_the_kept_children():
    torch.manual_seed(5)
    half = D // 2
    coarse = shapes(5)
    coarse = coarse[(coarse[:, 1:] < half).all(dim=1)]  # parents inside a (D/2)³ grid
    feats = torch.randn(len(coarse), 3, dtype=torch.float64, requires_grad=True)
    x = SparseTensor.build(coarse, feats, level=1)
    keep = torch.rand(len(coarse), 8) < 0.4
    child = SparseTensor.build(expand_children(x, keep), torch.zeros(int(keep.sum()), 0), level=0)
    w_t = torch.randn(3, 4, 2, 2, 2, dtype=torch.float64, requires_grad=True)  # [C_in, C_out, 2,2,2]
    bias = torch.randn(4, dtype=torch.float64, requires_grad=True)
    y = subdivide_conv3d(x, child, w_t.permute(2, 3, 4, 0, 1).reshape(8, 3, 4), bias)
    ref = gather(F.conv_transpose3d(dense(x.coords, x.feats, side=half), w_t, bias, stride=2), child.coords)
    torch.testing.assert_close(y.feats, ref)
    assert_same_gradients(y.feats, ref, (feats, w_t, bias))


def test_keys_round_trip_and_order():
    c = torch.tensor([[0, 0, 0, 0], [0, 0, 0, 1], [0, 0, 1, 0], [0, 1, 0, 0], [1, 0, 0, 0],
                      [2, 4096, 4096, 4096]], dtype=torch.int32)
    k = hash_coords(c)
    assert bool((k[1:] > k[:-1]).all())
    assert torch.equal(unhash(k), c)
    with pytest.raises(ValueError, match="duplicate"):
        SparseTensor.build(torch.cat([c, c[:1]]), torch.zeros(7, 1))
