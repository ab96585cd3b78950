"""`encode --format trellis2`: our latents in the layout TRELLIS.2's structured-latent dataset
reads, inside a `sparc3d export --format trellis2` folder of the same job, and `decode` of them.

Read here by a port of TRELLIS.2's loading path (microsoft/TRELLIS.2 at
`trellis2_latents.TRELLIS2_COMMIT`): `trellis2/datasets/components.py`
`StandardDatasetBase.__init__` (the `--data_dir` JSON object, one `metadata.csv` per listed
folder combined on `sha256`) and `trellis2/datasets/structured_latent.py` `SLat`
(`filter_metadata`, `get_instance`: `coords` `.int()`, `feats` `.float()`, then
`(feats - mean) / std`). The same checks were run once against its own code (docs/VAE.md,
"Latents for TRELLIS.2's flow"); this port keeps them without fetching it.
"""

import csv
import json
import os
import shutil

import numpy as np
import pytest
import torch
import trimesh

import sparc3d_reader as reader
from conftest import make_job, run
from sparc3d_vae import cli, infer
from sparc3d_vae import trellis2_latents as t2
from sparc3d_vae.runtime import load_checkpoint

#: TRELLIS.2's grid of the job (`--for trellis2@G`: the job converts at G + 6).
GRID = 32
MESHES = ["sphere.obj", "wuson.stl", "cube.off"]
#: A small network, trained just long enough for its decoder to hold a surface.
SMALL = """[model]
channels = [16, 16, 32, 32]
blocks = [0, 1, 1, 1]
downsample = 8
heads = 2
[train]
batch_size = 3
threads = 1
checkpoint_every = 1000
augment_rotations = false
ema_decay = 0.0
"""
STEPS = 40
#: `configs/gen/slat_flow_img2shape_dit_1_3B_512_bf16.json`'s dataset filters.
MIN_AESTHETIC, MAX_TOKENS = 4.5, 8192


def export(job, out):
    """`sparc3d export JOB --format trellis2 --out OUT` (in TRELLIS.2's frame)."""
    run("export", job, "--format", "trellis2", "--out", out)
    return out


@pytest.fixture(scope="module")
def encoded(tmp_path_factory):
    """A trellis2@32 job of three meshes, a VAE trained on it, its export with the latents."""
    tmp = tmp_path_factory.mktemp("t2lat")
    job = make_job(tmp, None, MESHES, preset=f"trellis2@{GRID}")
    (tmp / "small.toml").write_text(SMALL)
    from sparc3d_vae import train
    train.train([str(job)], tmp / "run", tmp / "small.toml", STEPS, "cpu", resume=False)
    out = export(job, tmp / "export")
    summary = t2.encode(tmp / "run", [str(job)], out, "cpu")
    return {"tmp": tmp, "job": job, "run": tmp / "run", "export": out, "summary": summary}


# --- The port of TRELLIS.2's loading path ------------------------------------------------------

def combined_metadata(root):
    """`StandardDatasetBase.__init__` for one source of the JSON object: every listed folder's
    `metadata.csv` combined on sha256 (with pandas as upstream when installed, else the csv
    module: pandas reads the literal `True` as a boolean and the numbers as numbers)."""
    try:
        import pandas as pd
    except ImportError:
        rows = {}
        for folder in root.values():
            with open(os.path.join(folder, "metadata.csv"), newline="") as f:
                for r in csv.DictReader(f):
                    rows.setdefault(r["sha256"], {}).update(r)
        return {sha: rows[sha] for sha in sorted(rows)}
    metadata = pd.DataFrame(columns=["sha256"]).set_index("sha256")
    for folder in root.values():
        metadata = metadata.combine_first(
            pd.read_csv(os.path.join(folder, "metadata.csv")).set_index("sha256"))
    return {sha: {k: str(v) for k, v in row.items()} for sha, row in metadata.iterrows()}


def slat_filter(metadata, key, min_aesthetic, max_tokens):
    """`SLat.filter_metadata`: encoded, aesthetic score and token count (the columns it reads,
    `aesthetic_score` among them: a missing column is a KeyError, as upstream)."""
    return [sha for sha, r in metadata.items()
            if r.get(f"{key}_encoded") == "True"
            and float(r["aesthetic_score"]) >= min_aesthetic
            and float(r[f"{key}_tokens"]) <= max_tokens]


class SLatPort:
    """`SLat(roots, min_aesthetic_score, max_tokens, latent_key, normalization)`: its instances,
    `loads` and `get_instance`."""

    def __init__(self, roots, key, normalization, min_aesthetic=MIN_AESTHETIC,
                 max_tokens=MAX_TOKENS):
        self.key, self.instances, self.loads = key, [], []
        for root in json.loads(roots).values():
            metadata = combined_metadata(root)
            for sha in slat_filter(metadata, key, min_aesthetic, max_tokens):
                self.instances.append((root, sha))
                self.loads.append(int(float(metadata[sha][f"{key}_tokens"])))
        self.mean = torch.tensor(normalization["mean"]).reshape(1, -1)
        self.std = torch.tensor(normalization["std"]).reshape(1, -1)

    def get_instance(self, root, sha):
        data = np.load(os.path.join(root[self.key], f"{sha}.npz"))
        coords = torch.tensor(data["coords"]).int()
        feats = torch.tensor(data["feats"]).float()
        return {"coords": coords, "feats": (feats - self.mean) / self.std}


def with_aesthetic_scores(export_dir, folder, score=5.0):
    """The export's `--data_dir` object with one more folder: a `metadata.csv` of
    `aesthetic_score` (not ours to know, docs/FORMAT.md), as a user adds it."""
    (dataset, root), = json.loads((export_dir / "data_dir.json").read_text()).items()
    folder.mkdir(exist_ok=True)
    with open(export_dir / "metadata.csv", newline="") as f:
        shas = [r["sha256"] for r in csv.DictReader(f)]
    (folder / "metadata.csv").write_text(
        "sha256,aesthetic_score\n" + "".join(f"{s},{score}\n" for s in shas))
    return json.dumps({dataset: {**root, "aesthetic_score": str(folder)}}), shas


def latent_folder(export_dir, key="shape_latent"):
    (root,) = json.loads((export_dir / "data_dir.json").read_text()).values()
    return root[key]


# --- What SLat reads ----------------------------------------------------------------------------

def test_slat_loads_every_item_in_the_latent_grid_normalised_by_the_stats_beside_them(encoded):
    tmp, out = encoded["tmp"], encoded["export"]
    roots, shas = with_aesthetic_scores(out, tmp / "aesthetic")
    folder = latent_folder(out)
    stats = json.loads(open(os.path.join(folder, "normalization.json")).read())
    ds = SLatPort(roots, "shape_latent", stats)
    assert sorted(sha for _, sha in ds.instances) == sorted(shas)  # every item of the export
    model = load_checkpoint(encoded["run"])["config"]["model"]
    resolution = json.loads((encoded["job"] / "job.json").read_text())["config"]["params"]["resolution"]
    grid = -(-resolution // model["downsample"])  # the latent grid of the job
    mean, std = np.array(stats["mean"], np.float32), np.array(stats["std"], np.float32)
    raw = []
    for (root, sha), load in zip(ds.instances, ds.loads):
        item = ds.get_instance(root, sha)
        c, f = item["coords"], item["feats"]
        assert c.dtype == torch.int32 and c.shape[1] == 3, sha
        assert int(c.min()) >= 0 and int(c.max()) < grid, (sha, int(c.max()), grid)
        assert f.shape == (len(c), model["latent_channels"]) and load == len(c), sha
        z = np.load(os.path.join(folder, f"{sha}.npz"))
        assert np.allclose(f.numpy(), (z["feats"] - mean) / std, atol=1e-6), sha
        raw.append(z["feats"].astype(np.float64))
    # The stats are every token's per-channel mean and (population) standard deviation.
    tokens = np.concatenate(raw)
    assert np.allclose(mean, tokens.mean(axis=0), atol=1e-6)
    assert np.allclose(std, tokens.std(axis=0), atol=1e-6)
    normalised = np.concatenate([ds.get_instance(r, s)["feats"].numpy() for r, s in ds.instances])
    assert np.allclose(normalised.mean(axis=0), 0, atol=1e-5)
    assert np.allclose(normalised.std(axis=0), 1, atol=1e-4)


def test_latents_are_the_posterior_mean_of_each_item_keyed_by_its_sha256(encoded, tmp_path):
    out, folder = encoded["export"], latent_folder(encoded["export"])
    infer.encode(encoded["run"], [str(encoded["job"])], tmp_path / "pq", "cpu")
    rows = {r["id"]: r for r in reader.iter_tensor_rows(tmp_path / "pq", infer.LATENT_TENSORS)}
    with open(out / "metadata.csv", newline="") as f:
        ids = {r["sha256"]: r["id"] for r in csv.DictReader(f)}
    with open(os.path.join(folder, "metadata.csv"), newline="") as f:
        listed = list(csv.DictReader(f))
    assert [r["sha256"] for r in listed] == list(ids)  # the export's items, in its order
    for r in listed:
        z = np.load(os.path.join(folder, f"{r['sha256']}.npz"))
        ours = rows[ids[r["sha256"]]]
        assert str(z["id"]) == ids[r["sha256"]]
        assert np.array_equal(z["coords"], ours["coords"]) and np.array_equal(z["feats"], ours["mean"])
        assert r["shape_latent_encoded"] == "True" and int(r["shape_latent_tokens"]) == len(z["coords"])
    # data_dir.json keeps the export's folders and adds the latent one.
    (root,) = json.loads((out / "data_dir.json").read_text()).values()
    assert {"base", "mesh_dump", "dual_grid", "asset_stats", "shape_latent"} <= set(root)
    assert root["shape_latent"] == str(out / "shape_latents" / os.path.basename(folder))


# --- Back to our mesh ---------------------------------------------------------------------------

def ply(path):
    m = trimesh.load(path, process=False)
    return np.asarray(m.vertices), np.asarray(m.faces)


def test_decoding_a_latent_read_back_gives_the_mesh_of_reconstruct(encoded, tmp_path, binary):
    run_dir, out, folder = encoded["run"], encoded["export"], latent_folder(encoded["export"])
    roots, _ = with_aesthetic_scores(out, tmp_path / "aesthetic")
    stats_file = os.path.join(folder, "normalization.json")
    ds = SLatPort(roots, "shape_latent", json.loads(open(stats_file).read()))
    resolution = json.loads(open(os.path.join(folder, t2.LATENT_RECORD)).read())["resolution"]
    for root, sha in ds.instances:
        z = np.load(os.path.join(folder, f"{sha}.npz"))
        item_id = str(z["id"])
        rec = infer.reconstruct(run_dir, [str(encoded["job"])], item_id, tmp_path / "rec.ply",
                                "cpu", True, binary, None)
        # The export's file as it is: the same bytes as reconstruct's mesh.
        (dec,) = infer.decode(run_dir, folder, [sha], tmp_path / "dec", "cpu", True, binary)
        assert "error" not in dec, dec
        assert open(dec["output"], "rb").read() == (tmp_path / "rec.ply").read_bytes(), sha
        # What SLat hands the flow (normalised), as a bare sample: un-normalised, it decodes
        # to the same faces, in the job grid's [-0.5, 0.5] frame.
        item = ds.get_instance(root, sha)
        bare = tmp_path / "bare" / f"{sha}.npz"
        bare.parent.mkdir(exist_ok=True)
        np.savez(bare, coords=item["coords"].numpy(), feats=item["feats"].numpy())
        (back,) = infer.decode(run_dir, bare, None, tmp_path / "back", "cpu", True, binary,
                               normalized_by=stats_file, resolution=resolution)
        v, f = ply(back["output"])
        v0, f0 = ply(tmp_path / "rec.ply")
        assert rec["faces"] == back["faces"] and np.array_equal(f, f0), sha
        assert np.allclose(v, (v0 - z["center"]) * float(z["scale"]), atol=1e-5), sha


# --- Deterministic, and clear about what it cannot do -------------------------------------------

def tree_bytes(folder):
    return {p: open(os.path.join(folder, p), "rb").read() for p in sorted(os.listdir(folder))}


def test_encoding_again_gives_the_same_bytes(encoded):
    out, folder = encoded["export"], latent_folder(encoded["export"])
    before = tree_bytes(folder), (out / "data_dir.json").read_bytes()
    t2.encode(encoded["run"], [str(encoded["job"])], out, "cpu")
    assert (tree_bytes(folder), (out / "data_dir.json").read_bytes()) == before
    assert not [p for p in os.listdir(os.path.dirname(folder)) if p.startswith(".")]


def run_cli(capsys, *args):
    code = cli.main([str(a) for a in args])
    return code, capsys.readouterr().err


def test_an_item_that_does_not_fit_is_left_out_and_named(encoded, tmp_path, capsys):
    out = export(encoded["job"], tmp_path / "export")
    from sparc3d_vae.loaded import Loaded
    samples = Loaded(encoded["run"], "cpu").load_samples([str(encoded["job"])])
    cells = sorted((len(samples[i].cells), samples.ids[i]) for i in range(len(samples)))
    code, err = run_cli(capsys, "encode", "--ckpt", encoded["run"], "--data", encoded["job"],
                        "--format", "trellis2", "--out", out, "--device", "cpu",
                        "--max-cells", cells[0][0])
    assert code == 1, err
    for _, big in cells[1:]:
        assert big in err and "--max-cells" in err, err
    with open(os.path.join(latent_folder(out), "metadata.csv"), newline="") as f:
        (row,) = list(csv.DictReader(f))
    ids = {r["sha256"]: r["id"] for r in csv.DictReader(open(out / "metadata.csv", newline=""))}
    assert ids[row["sha256"]] == cells[0][1]


def test_what_is_not_a_trellis2_export_of_the_job_is_refused(encoded, tmp_path, capsys):
    def encode(out, job=encoded["job"], *more):
        return run_cli(capsys, "encode", "--ckpt", encoded["run"], "--data", job, "--format",
                       "trellis2", "--device", "cpu", "--out", out, *more)

    code, err = encode(tmp_path / "nothing")
    assert code == 2 and ".sparc3d-export.json" in err and "sparc3d export" in err, err
    out = export(encoded["job"], tmp_path / "export")
    (out / "metadata.csv").unlink()
    code, err = encode(out)
    assert code == 2 and "without metadata.csv" in err, err
    # An export of another job: refused by the fingerprint of the job it was made from.
    other = tmp_path / "other"
    other.mkdir()
    job2 = make_job(other, None, ["cube.off"], preset=f"trellis2@{GRID + 8}")
    code, err = encode(export(encoded["job"], tmp_path / "e2"), job2)
    assert code == 2 and "fingerprint" in err, err
    # A folder of someone else's where the latents would go is left alone.
    out = export(encoded["job"], tmp_path / "e3")
    (out / "shape_latents" / "mine").mkdir(parents=True)
    code, err = encode(out, encoded["job"], "--latent-name", "mine")
    assert code == 2 and "not ours" in err, err
    code, err = run_cli(capsys, "encode", "--ckpt", encoded["run"], "--data", encoded["job"],
                        "--out", tmp_path / "pq", "--latent-name", "x")
    assert code == 2 and "--format trellis2" in err, err


def test_decode_reports_a_bad_file_and_meshes_the_others(encoded, tmp_path, capsys, binary):
    folder = latent_folder(encoded["export"])
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    good = sorted(p for p in os.listdir(folder) if p.endswith(".npz"))[0]
    shutil.copy(os.path.join(folder, good), mixed / good)
    (mixed / "broken.npz").write_bytes(b"not a zip")
    channels = load_checkpoint(encoded["run"])["config"]["model"]["latent_channels"]
    np.savez(mixed / "bare.npz", coords=np.zeros((1, 3), np.int32),
             feats=np.zeros((1, channels), np.float32))
    code, err = run_cli(capsys, "decode", "--ckpt", encoded["run"], "--latents", mixed, "--all",
                        "--out", tmp_path / "meshes", "--device", "cpu", "--sparc3d", binary)
    assert code == 1
    assert "broken.npz: not a readable npz" in err and "bare.npz: no `resolution`" in err, err
    assert "--resolution" in err
    assert (tmp_path / "meshes" / (str(np.load(mixed / good)["id"]) + ".ply")).is_file()
    code, err = run_cli(capsys, "decode", "--ckpt", encoded["run"], "--latents", mixed, "--id",
                        "nope", "--out", tmp_path / "m2", "--device", "cpu", "--sparc3d", binary)
    assert code == 2 and "'nope'" in err, err
    # The export itself is no latent folder: the error names the one it lists.
    code, err = run_cli(capsys, "decode", "--ckpt", encoded["run"], "--latents",
                        encoded["export"], "--all", "--out", tmp_path / "m3", "--device", "cpu",
                        "--sparc3d", binary)
    assert code == 2 and "is a TRELLIS.2 export" in err and f"shape_latent: {folder}" in err, err
