"""Runs TRELLIS.2's own structured-latent datasets (`SLat`, `SLatShape` and, when the export
has condition views, `ImageConditionedSLatShape`, the dataset the flow config names) on every
item of a `sparc3d export --format trellis2` folder holding `sparc3d-vae encode --format
trellis2` latents, and decodes what they hand the flow back to our meshes
(docs/LATENTS_TRELLIS2.md).

    python ops/peers/trellis2_slat_load.py TRELLIS2 EXPORT_DIR RUN JOB_DIR \
        [--image-conditioned] [--image-size 512]

TRELLIS2 is a checkout of github.com/microsoft/TRELLIS.2 or a bare clone of it (its
`trellis2/` taken from HEAD by `git archive`; checked at commit
5565d240c4a494caaf9ece7a554542b76ffa36d3). Imported as they are:
`trellis2/datasets/{__init__,components,structured_latent,structured_latent_shape}.py`
(`ImageConditionedMixin` of `components.py` included), `trellis2/models/__init__.py` (lazy: no
model is built), `trellis2/modules/sparse/` (`SparseTensor`, for `collate_fn`) and
`trellis2/utils/data_utils.py`. Stubbed, being off the loading path: the package `__init__`s of
`trellis2` (models, pipelines, renderers) and `trellis2.utils`, `trellis2/utils/render_utils.py`
(`get_renderer`, `yaw_pitch_r_fov_to_extrinsics_intrinsics`: `visualize_sample` only) and
`utils3d` (its cameras). `aesthetic_score`, which `SLat.filter_metadata` needs and we do not
know, is given as one more folder of the `--data_dir` object (5.0 for every item).

When the export's `data_dir.json` lists `render_cond` (a job made with `--renders`;
`--image-conditioned` requires it), `ImageConditionedSLatShape(image_size=...)` (512, the flow
config's) must keep the same items, and each item's `get_instance`, seeded so that every view
of its `transforms.json` is drawn once, must give the latent SLat gives and a `cond` float32
(3, S, S) in [0, 1]: the view `NNN.png` cropped to its alpha's bounding square, resized and
premultiplied by its alpha (computed here from the file); `collate_fn` over the items must
stack the conds to (items, 3, S, S) beside the same `x_0`. Needs torch, numpy, pandas, PIL,
trimesh, sparc3d_vae and `sparc3d` (SPARC3D_BIN or on PATH). Exit 1 when an item fails to load
or disagrees.
"""

import argparse
import json
import os
import pathlib
import shutil
import sys
import tempfile

import numpy as np
from trellis2_code import linked_package, trellis2_source

#: The flow config's filters (`configs/gen/slat_flow_img2shape_dit_1_3B_512_bf16.json`).
DATASET_ARGS = {"min_aesthetic_score": 4.5, "max_tokens": 8192}
STUBS = {
    "trellis2/__init__.py": "",
    "trellis2/utils/__init__.py": "",
    "trellis2/utils/render_utils.py":
        "def get_renderer(*a, **k): raise NotImplementedError('stub')\n"
        "def yaw_pitch_r_fov_to_extrinsics_intrinsics(*a, **k): raise NotImplementedError('stub')\n",
    "utils3d/__init__.py": "from . import torch\n",
    "utils3d/torch.py": "",
}
AS_THEY_ARE = ["trellis2/datasets", "trellis2/models/__init__.py", "trellis2/modules/sparse",
               "trellis2/utils/data_utils.py"]


def import_datasets(checkout, tmp):
    """TRELLIS.2's `SLat`, `SLatShape` and `ImageConditionedSLatShape`, their files linked into
    a package with the stubs."""
    linked_package(tmp, checkout, STUBS, {rel: rel for rel in AS_THEY_ARE})
    from trellis2.datasets import ImageConditionedSLatShape, SLat, SLatShape
    return SLat, SLatShape, ImageConditionedSLatShape


def data_dir_with_scores(export, tmp):
    """The export's `--data_dir` object plus a folder of `aesthetic_score`; its sha256s."""
    (name, root), = json.loads((export / "data_dir.json").read_text()).items()
    shas = [line.split(",")[0] for line in (export / "metadata.csv").read_text().splitlines()[1:]]
    (tmp / "aesthetic").mkdir()
    (tmp / "aesthetic" / "metadata.csv").write_text(
        "sha256,aesthetic_score\n" + "".join(f"{s},5.0\n" for s in shas))
    return json.dumps({name: {**root, "aesthetic_score": str(tmp / "aesthetic")}}), root, shas


def check_items(ds, latents, record, norm):
    """Every instance through `get_instance` (its `__getitem__` would hide an error by drawing
    another item): coords in the latent grid, feats of the latent's channels, normalised by
    `norm`. Returns the number of items that disagree."""
    import torch
    mean, std = np.array(norm["mean"], np.float32), np.array(norm["std"], np.float32)
    bad = 0
    for i, (root, sha) in enumerate(ds.instances):
        item = ds.get_instance(root, sha)
        c, f = item["coords"], item["feats"]
        z = np.load(latents / f"{sha}.npz")
        ok = (c.dtype == torch.int32 and c.shape[1] == 3 and int(c.min()) >= 0
              and int(c.max()) < record["latent_grid"]
              and tuple(f.shape) == (len(c), record["latent_channels"])
              and torch.equal(c, torch.from_numpy(z["coords"]).int())
              and np.allclose(f.numpy(), (z["feats"] - mean) / std, atol=1e-6)
              and ds.loads[i] == len(c))
        print(f"{sha[:16]}  coords {tuple(c.shape)} max {int(c.max())}  feats {tuple(f.shape)} "
              f"mean {float(f.mean()):.3f} std {float(f.std()):.3f}  {'ok' if ok else 'DISAGREES'}")
        bad += not ok
    return bad


def expected_cond(path, size):
    """What `ImageConditionedMixin.get_instance` makes of one view, from the file: cropped to
    the square about its alpha's bounding box, resized (Lanczos) to `size`, RGB premultiplied
    by alpha, in [0, 1], channels first."""
    from PIL import Image
    image = Image.open(path)
    ys, xs = np.asarray(image.getchannel(3)).nonzero()
    cx, cy = (xs.min() + xs.max()) / 2, (ys.min() + ys.max()) / 2
    h = max(xs.max() - xs.min(), ys.max() - ys.min()) / 2
    image = image.crop([int(cx - h), int(cy - h), int(cx + h), int(cy + h)])
    image = image.resize((size, size), Image.Resampling.LANCZOS)
    rgba = np.asarray(image, np.float32) / 255.0
    return (rgba[..., :3] * rgba[..., 3:]).transpose(2, 0, 1)


def view_seeds(n_views):
    """For each view, a seed after which `np.random.randint(n_views)` draws it (the mixin's
    draw), so that seeding before `get_instance` loads every view once."""
    seeds = {}
    for seed in range(10000):
        np.random.seed(seed)
        seeds.setdefault(int(np.random.randint(n_views)), seed)
        if len(seeds) == n_views:
            return [seeds[v] for v in range(n_views)]
    raise RuntimeError(f"no seed draws every one of {n_views} views")


def check_image_conditioned(ic, ds, size):
    """Every item of `ImageConditionedSLatShape` through `get_instance` once per view of its
    `transforms.json`: the latent equal to SLat's of the item and `cond` the view as the mixin
    makes it; then `collate_fn` over the items as loaded with view 0. Returns the number of
    (item, view) loads that disagree, plus one when the collated `cond` is not (items, 3, S, S)."""
    import torch
    bad, first = 0, []
    for root, sha in ic.instances:
        want = ds.get_instance(root, sha)
        folder = pathlib.Path(root["render_cond"]) / sha
        frames = json.loads((folder / "transforms.json").read_text())["frames"]
        shapes, lo, hi, agree = set(), 1.0, 0.0, 0
        for view, seed in enumerate(view_seeds(len(frames))):
            np.random.seed(seed)
            item = ic.get_instance(root, sha)
            cond = item["cond"]
            ref = expected_cond(folder / f"{view:03d}.png", size)
            ok = (torch.equal(item["coords"], want["coords"])
                  and torch.equal(item["feats"], want["feats"])
                  and cond.dtype == torch.float32 and tuple(cond.shape) == (3, size, size)
                  and float(cond.min()) >= 0 and float(cond.max()) <= 1
                  and float(cond.max()) > 0 and np.allclose(cond.numpy(), ref, atol=1e-6))
            bad += not ok
            agree += ok
            shapes.add(tuple(cond.shape))
            lo, hi = min(lo, float(cond.min())), max(hi, float(cond.max()))
            if view == 0:
                first.append(item)
            if not ok:
                print(f"{sha[:16]}  view {view:03d} ({frames[view]['file_path']})  DISAGREES")
        print(f"{sha[:16]}  {agree} of {len(frames)} views ok: cond {sorted(shapes)} in "
              f"[{lo:.3f}, {hi:.3f}]")
    pack = type(ic).collate_fn(first)
    print(f"collate_fn: cond {tuple(pack['cond'].shape)}, x_0 feats "
          f"{tuple(pack['x_0'].feats.shape)}")
    bad += tuple(pack["cond"].shape) != (len(first), 3, size, size)
    return bad


def collated_samples(ds, out):
    """`collate_fn` over every item (what the flow trains on), cut back per item by its layout
    into bare npz (normalised coords/feats, as a sample of the flow would be)."""
    pack = type(ds).collate_fn([ds[i] for i in range(len(ds))])
    x = pack["x_0"]
    print(f"collate_fn: feats {tuple(x.feats.shape)}, coords {tuple(x.coords.shape)}, "
          f"shape {list(x.shape)}")
    out.mkdir()
    for (_, sha), part in zip(ds.instances, x.get_spatial_cache("layout")):
        np.savez(out / f"{sha}.npz", coords=x.coords[part, 1:].numpy(), feats=x.feats[part].numpy())
    return out


def check_decoded(samples, latents, record, run, job, binary, tmp):
    """Each sample decoded with `--normalized-by`: the faces of `reconstruct`'s mesh of the item
    and its vertices in the job grid's frame. Returns the number that disagree."""
    import trimesh
    from sparc3d_vae import infer
    back = infer.decode(run, samples, None, tmp / "back", "cpu", True, binary,
                        normalized_by=latents / "normalization.json",
                        resolution=record["resolution"])
    bad = 0
    for r in back:
        z = np.load(latents / f"{r['id']}.npz")
        rec = tmp / "rec.ply"
        infer.reconstruct(run, [str(job)], str(z["id"]), rec, "cpu", True, binary, None)
        a, b = (trimesh.load(p, process=False) for p in (r["output"], rec))
        far = np.abs(a.vertices - (b.vertices - z["center"]) * float(z["scale"])).max()
        ok = np.array_equal(a.faces, b.faces) and far < 1e-5
        print(f"{r['id'][:16]}  {len(a.faces)} faces, equal to reconstruct's: "
              f"{np.array_equal(a.faces, b.faces)}; vertices within {far:.1e}")
        bad += not ok
    return bad


def main():
    args = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    for name in ("trellis2", "export", "run", "job"):
        args.add_argument(name, type=lambda a: pathlib.Path(a).resolve())
    args.add_argument("--image-conditioned", action="store_true",
                      help="require render_cond in the export (else checked when it is there)")
    args.add_argument("--image-size", type=int, default=512,
                      help="ImageConditionedSLatShape's image_size (the flow config's: 512)")
    args = args.parse_args()
    export, run, job = args.export, args.run, args.job
    binary = os.environ.get("SPARC3D_BIN") or shutil.which("sparc3d") or "sparc3d"
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        checkout, commit = trellis2_source(args.trellis2, tmp, ["trellis2"])
        print(f"TRELLIS.2 at {commit}")
        slat, slat_shape, ic_slat_shape = import_datasets(checkout, tmp)
        roots, root, shas = data_dir_with_scores(export, tmp)
        latents = pathlib.Path(root["shape_latent"])
        norm = json.loads((latents / "normalization.json").read_text())
        record = json.loads((latents / ".sparc3d-latents.json").read_text())
        ds = slat(roots, latent_key="shape_latent", normalization=norm, **DATASET_ARGS)
        print(ds)
        bad = abs(len(ds) - len(shas)) + check_items(ds, latents, record, norm)
        shape = slat_shape(roots, resolution=record["dual_grid"], normalization=norm,
                           **DATASET_ARGS)
        print(f"SLatShape: {len(shape)} instances")
        bad += [s for _, s in shape.instances] != [s for _, s in ds.instances]
        if "render_cond" in root:
            ic = ic_slat_shape(roots, resolution=record["dual_grid"], normalization=norm,
                               image_size=args.image_size, **DATASET_ARGS)
            print(ic)
            bad += [s for _, s in ic.instances] != [s for _, s in ds.instances]
            bad += check_image_conditioned(ic, ds, args.image_size)
        elif args.image_conditioned:
            print("the export lists no render_cond (export a job made with --renders)")
            bad += 1
        else:
            print("ImageConditionedSLatShape: not checked, the export lists no render_cond")
        samples = collated_samples(ds, tmp / "samples")
        bad += check_decoded(samples, latents, record, run, job, binary, tmp)
    print(f"{bad} disagreements")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
