"""Runs TRELLIS.2's own `FlexiDualGridDataset` (`trellis2/datasets/flexi_dual_grid.py`) and
`SparseVoxelPbrDataset` (`trellis2/datasets/sparse_voxel_pbr.py`) on every item of a `sparc3d
export --format trellis2` folder of a job made with `--for trellis2@G` (docs/FORMAT.md,
"TRELLIS.2's dual grid dataset"), and counts where the dual grid disagrees with the mesh the
dataset's own `read_mesh` returns.

    python ops/peers/trellis2_dual_grid_load.py TRELLIS2 EXPORT_DIR --grid G

TRELLIS2 is a checkout of github.com/microsoft/TRELLIS.2 or a bare clone of it (its
`trellis2/` and `o-voxel/` taken from HEAD by `git archive`; checked at commit
5565d240c4a494caaf9ece7a554542b76ffa36d3). Imported as they are:
`trellis2/datasets/` (`components.py`, `flexi_dual_grid.py`, `sparse_voxel_pbr.py`),
`trellis2/modules/sparse/` (`SparseTensor`, `sparse_cat`), `trellis2/modules/utils.py`,
`trellis2/representations/` (`Mesh`, which `read_mesh` builds), `trellis2/utils/data_utils.py`,
and o_voxel's `io/vxz.py` (`read_vxz`, the reader both datasets call), `io/npz.py` and
`serialize.py` (`decode_seq`). Stubbed, being off the loading path: the package `__init__`s of
`trellis2` (models, pipelines, renderers), `trellis2.utils` and `o_voxel` (its `convert`,
`rasterize`, `postprocess` need the CUDA build), `trellis2.renderers` (`MeshRenderer`,
`VoxelRenderer`: `visualize_sample` only), `cumesh` and `flex_gemm` (imported by
`representations/mesh/base.py` for methods the loading path does not call), `utils3d`
(cameras, `visualize_sample` only), `plyfile` (`io/ply.py`, not called) and o_voxel's compiled
`_C`, whose two functions `read_vxz` calls on the CPU are given in Python here, ported from
its own sources: `decode_sparse_voxel_octree_cpu` (`o-voxel/src/io/svo.cpp`: the octree walk
of `tests/python/vxz_reader.py` `octree_codes`, which is the same pre-order walk) and
`z_order_decode_cpu` (`src/serialize/z_order.cu` `extractBits`).

Per item: `FlexiDualGridDataset.get_instance` (`read_mesh`, with its range assert, and
`read_dual_grid`); the mesh it returns against the dump as written (`read_mesh` should move
nothing: its centre 0 and scale 1); TRELLIS.2's crossing rule (`intersect_qef` of
`o-voxel/src/convert/flexible_dual_grid.cpp`, C++ only, so its numpy port `crossed_flags` of
`tests/python/test_grid_exports.py`) on that mesh against the `intersected` bits the dataset
read, both ways; each dual vertex `(coord + vertices) / G − 0.5` inside its voxel. Then
`SparseVoxelPbrDataset` (the texture VAE config's args, `with_mesh` false) on the items with
`pbr_voxels`: its `x.coords` equal to the dual grid's (`torch.equal`, as `SLatPbr` asserts of
the latents), feats in [−1, 1]; `collate_fn` of both over all items. Needs torch, numpy,
pandas, zstandard, PIL. Exit 1 on any disagreement or loading error.
"""

import argparse
import json
import os
import pathlib
import sys
import tempfile

import numpy as np
from trellis2_code import linked_package, trellis2_source

HERE = pathlib.Path(__file__).resolve().parent
TESTS = HERE.parent.parent / "tests" / "python"

#: `_C`'s CPU functions that `read_vxz` and `decode_seq` call, in Python.
C_STUB = '''
import sys
import numpy as np
import torch
sys.path.insert(0, %r)
from vxz_reader import octree_codes


def decode_sparse_voxel_octree_cpu(svo, depth):
    """o-voxel/src/io/svo.cpp: the Morton codes of the octree's leaves, pre-order (ascending)."""
    return torch.tensor(octree_codes(svo.numpy().tobytes(), int(depth)), dtype=torch.int32)


def _extract(v):
    v = v & 0x49249249
    v = (v ^ (v >> 2)) & 0x030C30C3
    v = (v ^ (v >> 4)) & 0x0300F00F
    v = (v ^ (v >> 8)) & 0x030000FF
    v = (v ^ (v >> 16)) & 0x000003FF
    return v


def z_order_decode_cpu(codes):
    """o-voxel/src/serialize/z_order.cu CPU::z_order_decode (x at bit 3b+2, y 3b+1, z 3b)."""
    c = codes.numpy().astype(np.int64) & 0xFFFFFFFF
    return tuple(torch.from_numpy(_extract(c >> s).astype(np.int32)) for s in (2, 1, 0))
'''

STUBS = {
    "trellis2/__init__.py": "",
    "trellis2/utils/__init__.py": "",
    "trellis2/renderers/__init__.py":
        "class MeshRenderer:\n    def __init__(self, *a, **k): raise NotImplementedError('stub')\n"
        "class VoxelRenderer:\n    def __init__(self, *a, **k): raise NotImplementedError('stub')\n",
    "utils3d/__init__.py": "from . import torch\n",
    "utils3d/torch.py": "",
    "cumesh/__init__.py": "",
    "flex_gemm/__init__.py": "",
    "flex_gemm/ops/__init__.py": "",
    "flex_gemm/ops/grid_sample.py":
        "def grid_sample_3d(*a, **k): raise NotImplementedError('stub')\n",
    "plyfile/__init__.py": "",
    "o_voxel/__init__.py": "from . import io, serialize\n",
    "o_voxel/_C.py": C_STUB % str(TESTS),
}
AS_THEY_ARE = {
    "trellis2/datasets": "trellis2/datasets",
    "trellis2/modules": "trellis2/modules",
    "trellis2/representations": "trellis2/representations",
    "trellis2/utils/data_utils.py": "trellis2/utils/data_utils.py",
    "o_voxel/io": "o-voxel/o_voxel/io",
    "o_voxel/serialize.py": "o-voxel/o_voxel/serialize.py",
}
#: The texture SC-VAE config's dataset args (`configs/scvae/tex_vae_next_dc_f16c32_fp16.json`).
PBR_ARGS = {"max_active_voxels": 1000000, "max_num_faces": 1000000, "with_mesh": False,
            "attrs": ["base_color", "metallic", "roughness", "alpha"]}


def import_datasets(checkout, tmp):
    """TRELLIS.2's two datasets, their files linked into a package with the stubs."""
    linked_package(tmp / "pkg", checkout, STUBS, AS_THEY_ARE, [TESTS])
    from trellis2.datasets import FlexiDualGridDataset, SparseVoxelPbrDataset
    return FlexiDualGridDataset, SparseVoxelPbrDataset


def dump_vertices(root, sha):
    """The mesh dump's vertices as written (float32, one object)."""
    import pickle
    with open(os.path.join(root["mesh_dump"], f"{sha}.pickle"), "rb") as f:
        return np.concatenate([o["vertices"] for o in pickle.load(f)["objects"]])


def check_dual_grid(ds, grid):
    """Every item through `get_instance` (its `__getitem__` would hide an error by drawing
    another item). Returns (disagreements, loaded items, totals)."""
    import torch
    from test_grid_exports import crossed_flags
    bad, items, total = 0, [], {"bits": 0, "differ": 0}
    for root, sha in ds.instances:
        item = ds.get_instance(root, sha)
        mesh = item["mesh"][0]
        v, f = mesh.vertices.numpy(), mesh.faces.numpy()
        moved = float(np.abs(v - dump_vertices(root, sha)).max()) * grid
        coords = item["vertices"].coords[:, 1:].numpy()
        local = item["vertices"].feats.numpy()
        bits = item["intersected"].feats.numpy()
        ours = {(*map(int, c), a) for c, b in zip(coords, bits) for a in range(3) if b[a]}
        theirs = crossed_flags(v, f, grid)
        only_ours, only_theirs = len(ours - theirs), len(theirs - ours)
        # The dual vertex at (coord + local)/G - 0.5 lies in its voxel by construction of
        # read_dual_grid (local in [0, 1]); the voxel must lie in the grid.
        in_grid = bool(coords.min() >= 0 and coords.max() < grid
                       and local.min() >= 0 and local.max() <= 1)
        ok = moved == 0 and only_ours == 0 and only_theirs == 0 and in_grid
        print(f"{sha[:16]}  voxels {len(coords)}  faces {len(f)}  read_mesh moved "
              f"{moved:.3g} voxel  bits {len(ours)}: {only_ours} not crossed, {only_theirs} "
              f"crossed not set  {'ok' if ok else 'DISAGREES'}")
        total["bits"] += len(ours)
        total["differ"] += only_ours + only_theirs
        bad += not ok
        items.append((sha, item))
    batch = ds.collate_fn([i for _, i in items])
    n = sum(len(i["vertices"].coords) for _, i in items)
    ok = (batch["vertices"].feats.shape[0] == n and len(batch["mesh"]) == len(items)
          and batch["intersected"].feats.dtype == torch.bool)
    print(f"collate_fn: vertices {tuple(batch['vertices'].feats.shape)}, "
          f"{len(batch['mesh'])} meshes  {'ok' if ok else 'DISAGREES'}")
    return bad + (not ok), dict(items), total


def check_pbr(pbr, grid_items):
    """Every item of `SparseVoxelPbrDataset` through `get_instance`: the dual grid's voxels."""
    import torch
    bad, items = 0, []
    for root, sha in pbr.instances:
        x = pbr.get_instance(root, sha)["x"]
        same = torch.equal(x.coords, grid_items[sha]["vertices"].coords)
        ok = same and x.feats.shape[1] == 6 and float(x.feats.abs().max()) <= 1
        print(f"{sha[:16]}  pbr x {tuple(x.feats.shape)}  coords equal the dual grid's: {same}"
              f"  {'ok' if ok else 'DISAGREES'}")
        bad += not ok
        items.append({"x": x})
    batch = pbr.collate_fn(items)
    print(f"collate_fn: x {tuple(batch['x'].feats.shape)}, layout {pbr.layout}")
    return bad


def main():
    args = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    args.add_argument("trellis2", type=lambda a: pathlib.Path(a).resolve())
    args.add_argument("export", type=lambda a: pathlib.Path(a).resolve())
    args.add_argument("--grid", type=int, required=True, help="G of --for trellis2@G")
    args = args.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        checkout, commit = trellis2_source(args.trellis2, tmp, ["trellis2", "o-voxel/o_voxel"])
        print(f"TRELLIS.2 at {commit}")
        flexi, svpbr = import_datasets(checkout, tmp)
        roots = (args.export / "data_dir.json").read_text()  # the --data_dir object
        shas = [line.split(",")[0]
                for line in (args.export / "metadata.csv").read_text().splitlines()[1:]]
        ds = flexi(roots, resolution=args.grid, min_aesthetic_score=None)
        print(ds)
        bad = abs(len(ds) - len(shas))
        b, grid_items, total = check_dual_grid(ds, args.grid)
        bad += b
        print(f"intersected: {total['differ']} disagreements (set and not crossed, or crossed and "
              f"not set) with TRELLIS.2's rule on the mesh read_mesh returns, {total['bits']} "
              f"bits set")
        (root,) = json.loads((args.export / "data_dir.json").read_text()).values()
        if "pbr_voxel" in root:
            pbr = svpbr(roots, resolution=args.grid, min_aesthetic_score=None, **PBR_ARGS)
            print(pbr)
            bad += check_pbr(pbr, grid_items)
        else:
            print("SparseVoxelPbrDataset: not checked, the export has no pbr_voxels")
    print(f"{bad} disagreements")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
