"""Runs Step1X-3D's own data loader on a `sparc3d export --format step1x-3d`, and checks what
it hands over against the job's output meshes (docs/FORMAT.md, "What each consumer reads").

    python ops/peers/step1x3d_load.py STEP1X3D_CHECKOUT EXPORT_DIR JOB_DIR

STEP1X3D_CHECKOUT is a clone of github.com/stepfun-ai/Step1X-3D. Its
`step1x3d_geometry/data/base.py` (`BaseDataset`) and `utils/typing.py` are imported as they
are, with the `data:` section of `configs/train-geometry-autoencoder/michelangelo.yaml`; the
modules they import that its loading path does not use (cv2, imageio, PIL, torchvision's image
transforms, jaxtyping, omegaconf, typeguard) are stubbed. Needs torch, numpy, pyyaml, scipy,
trimesh and `sparc3d` (SPARC3D_BIN or on PATH). Exit 1 when an item fails to load or disagrees.
"""

import dataclasses
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

import numpy as np

STUBS = {
    "cv2.py": "",
    "imageio.py": "",
    "PIL/__init__.py": "Image = None\n",
    "PIL/Image.py": "",
    "torchvision/__init__.py": "from . import transforms\n",
    "torchvision/transforms.py": "class ColorJitter:\n    def __init__(self, *a, **k): pass\n"
                                 "class RandomRotation(ColorJitter): pass\n",
    "jaxtyping.py": "Bool = Complex = Float = Inexact = Int = Integer = Num = Shaped = UInt = object\n",
    "omegaconf.py": "class DictConfig(dict): pass\n",
    "typeguard.py": "def typechecked(f): return f\n",
}


def import_loader(checkout, tmp):
    """Step1X-3D's BaseDataModuleConfig and BaseDataset, its two files linked into a package
    whose `__init__` (models, systems: not the loading path) is left out."""
    for name, text in STUBS.items():
        (tmp / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp / name).write_text(text)
    pkg = tmp / "step1x3d_geometry"
    for sub in ["", "data", "utils"]:
        (pkg / sub).mkdir(parents=True, exist_ok=True)
        (pkg / sub / "__init__.py").write_text("")
    for rel in ["data/base.py", "utils/typing.py"]:
        os.symlink(checkout / "step1x3d_geometry" / rel, pkg / rel)
    sys.path[:0] = [str(tmp)]
    from step1x3d_geometry.data.base import BaseDataModuleConfig, BaseDataset
    return BaseDataModuleConfig, BaseDataset


def config(checkout, config_class, export):
    """The loader's config from michelangelo.yaml's `data:` section, reading `export`."""
    import yaml
    path = checkout / "configs/train-geometry-autoencoder/michelangelo.yaml"
    data = yaml.safe_load(path.read_text())["data"]
    fields = {f.name for f in dataclasses.fields(config_class)}
    cfg = config_class(**{k: v for k, v in data.items() if k in fields})
    cfg.root_dir = str(export)
    return cfg


def load_every_item(cfg, dataset_class):
    """Every uid of train/val/test through `_get_data` (its `__getitem__` would swallow an
    error and return another item) and one collated batch per split; shapes checked."""
    import torch
    for split in ["train", "val", "test"]:
        ds = dataset_class(cfg, split)
        for i in range(len(ds)):
            r = ds._get_data(i)
            shapes = (r["surface"].shape, r["rand_points"].shape, r["sdf"].shape)
            want = ((cfg.n_samples, 6), (cfg.n_supervision, 3), (cfg.n_supervision,))
            if shapes != want:
                raise SystemExit(f"{split} {ds.uids[i]}: shapes {shapes}, expected {want}")
        if len(ds):
            loader = torch.utils.data.DataLoader(ds, batch_size=min(2, len(ds)),
                                                 collate_fn=ds.collate)
            batch = next(iter(loader))
            print(f"{split}: {len(ds)} uids loaded; a batch: "
                  f"{ {k: tuple(v.shape) for k, v in batch.items() if hasattr(v, 'shape')} }")


def source_bounds(uri):
    """The source file's bounding box (OBJ read as its `v` lines: trimesh's OBJ reader wants
    the stubbed PIL for textures)."""
    if uri.lower().endswith(".obj"):
        with open(uri, errors="replace") as f:
            v = np.array([line.split()[1:4] for line in f if line.startswith("v ")], float)
        return v.min(0), v.max(0)
    import trimesh
    return trimesh.load(uri, force="mesh", skip_materials=True).bounds


def output_mesh(binary, job, item_id, out):
    """The item's output mesh in the source frame, from the job's shards."""
    import trimesh
    for shard in sorted((job / "shards").glob("part-*.parquet")):
        r = subprocess.run([binary, "extract", shard, "--id", item_id, "-o", out],
                           capture_output=True)
        if r.returncode == 0:
            return trimesh.load(out, force="mesh")
    raise SystemExit(f"{item_id}: in no shard of {job}")


def check_meaning(cfg, dataset_class, export, job, binary, tmp):
    """Per train uid, with the flip off: surface points on the output mesh placed in Step1X-3D's
    frame (the source's box centred, longest side ±1), sdf > 0 where the mesh's winding number
    says inside, on 400 points farther than 1e-3 from the surface. Returns the disagreements."""
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "tests/python"))
    from test_consumer_exports import distance_to, winding
    record = json.loads((export / ".sparc3d-export.json").read_text())
    ids = {item["stem"]: item["id"] for item in record["items"]}
    uris = {}
    for line in (job / "manifest.jsonl").read_text().splitlines():
        row = json.loads(line)
        uris[row["id"]] = row["uri"]
    cfg.random_flip = False
    ds = dataset_class(cfg, "train")
    bad = 0
    for i, uid in enumerate(ds.uids):
        lo, hi = source_bounds(uris[ids[uid]])
        mesh = output_mesh(binary, job, ids[uid], tmp / f"{uid}.ply")
        mesh.apply_translation(-(lo + hi) / 2)
        mesh.apply_scale(2 / (hi - lo).max())
        v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
        r = ds._get_data(i)
        surface = r["surface"][:2000, :3]
        dist = float(np.median(distance_to(v, f, surface)))
        far = np.abs(r["sdf"]) > 1e-3
        inside = winding(v, f, r["rand_points"][far][:400]) > 0.5
        agree = float(np.mean(inside == (r["sdf"][far][:400] > 0)))
        extent = np.abs(r["surface"][:, :3]).max(0)
        print(f"{ids[uid][:16]}  |surface| per axis {np.round(extent, 3)}  "
              f"median distance {dist:.1e}  sign agrees {agree:.4f}")
        bad += dist > 1e-3 or agree < 0.999 or not 0.99 < extent.max() < 1.03
    return bad


def main():
    checkout, export, job = (pathlib.Path(a).resolve() for a in sys.argv[1:4])
    binary = os.environ.get("SPARC3D_BIN") or shutil.which("sparc3d") or "sparc3d"
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        config_class, dataset_class = import_loader(checkout, tmp)
        cfg = config(checkout, config_class, export)
        load_every_item(cfg, dataset_class)
        bad = check_meaning(cfg, dataset_class, export, job, binary, tmp)
    print(f"{bad} items disagree")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
