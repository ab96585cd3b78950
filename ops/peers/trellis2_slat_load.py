"""Runs TRELLIS.2's own structured-latent datasets (`SLat`, `SLatShape`) on every item of a
`sparc3d export --format trellis2` folder holding `sparc3d-vae encode --format trellis2`
latents, and decodes what they hand the flow back to our meshes (docs/VAE.md, "Latents for
TRELLIS.2's flow").

    python ops/peers/trellis2_slat_load.py TRELLIS2_CHECKOUT EXPORT_DIR RUN JOB_DIR

TRELLIS2_CHECKOUT is a checkout of github.com/microsoft/TRELLIS.2 (checked at commit
5565d240c4a494caaf9ece7a554542b76ffa36d3). Imported as they are:
`trellis2/datasets/{__init__,components,structured_latent,structured_latent_shape}.py`,
`trellis2/models/__init__.py` (lazy: no model is built), `trellis2/modules/sparse/`
(`SparseTensor`, for `collate_fn`) and `trellis2/utils/data_utils.py`. Stubbed, being off the
loading path: the package `__init__`s of `trellis2` (models, pipelines, renderers) and
`trellis2.utils`, `trellis2/utils/render_utils.py` (`get_renderer`,
`yaw_pitch_r_fov_to_extrinsics_intrinsics`: `visualize_sample` only) and `utils3d` (its
cameras). `aesthetic_score`, which `SLat.filter_metadata` needs and we do not know, is given
as one more folder of the `--data_dir` object (5.0 for every item). Needs torch, numpy,
pandas, PIL, trimesh, sparc3d_vae and `sparc3d` (SPARC3D_BIN or on PATH). Exit 1 when an item
fails to load or disagrees.
"""

import json
import os
import pathlib
import shutil
import sys
import tempfile

import numpy as np

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
    """TRELLIS.2's `SLat` and `SLatShape`, their files linked into a package with the stubs."""
    for name, text in STUBS.items():
        (tmp / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp / name).write_text(text)
    for rel in AS_THEY_ARE:
        (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
        os.symlink(checkout / rel, tmp / rel)
    sys.path[:0] = [str(tmp)]
    from trellis2.datasets import SLat, SLatShape
    return SLat, SLatShape


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
    checkout, export, run, job = (pathlib.Path(a).resolve() for a in sys.argv[1:5])
    binary = os.environ.get("SPARC3D_BIN") or shutil.which("sparc3d") or "sparc3d"
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        slat, slat_shape = import_datasets(checkout, tmp)
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
        samples = collated_samples(ds, tmp / "samples")
        bad += check_decoded(samples, latents, record, run, job, binary, tmp)
    print(f"{bad} disagreements")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
