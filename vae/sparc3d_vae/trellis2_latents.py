"""Latents in the layout of TRELLIS.2's structured-latent datasets, inside a `sparc3d export
--format trellis2` folder, so that one data directory holds the dual grids, PBR voxels and
latents of the same items (keyed by the same sha256), and read back for `decode`.

What TRELLIS.2 reads (microsoft/TRELLIS.2 at commit `TRELLIS2_COMMIT`):

- `trellis2/datasets/structured_latent.py` `SLat.get_instance`: `np.load(root[latent_key] /
  f'{sha256}.npz')`, `coords` cast with `.int()` ([n, 3], the latent grid), `feats` with
  `.float()` ([n, C]), then `(feats - mean) / std` with the `normalization` its config gives;
- `SLat.filter_metadata`: `{latent_key}_encoded == True`, `aesthetic_score >=
  min_aesthetic_score`, `{latent_key}_tokens <= max_tokens`, over the metadata that
  `trellis2/datasets/components.py` `StandardDatasetBase.__init__` combines on `sha256` from the
  `metadata.csv` of every folder the `--data_dir` object names;
- `data_toolkit/encode_shape_latent.py` writes `shape_latents/<latent_name>/<sha256>.npz`
  (`feats` float32, `coords` uint8: the encoder's posterior mean, `FlexiDualGridVaeEncoder
  .forward` with `sample_posterior=False`) and records `sha256, shape_latent_encoded,
  shape_latent_tokens`, which `data_toolkit/build_metadata.py` `update_metadata` merges into
  that folder's `metadata.csv`; its README's flow commands name the folder `shape_latent` in
  `--data_dir`.

We write the same: `<latent_key>s/<latent_name>/<sha256>.npz` (`coords` int32 — SLat casts
with `.int()`, so int32 reads as uint8 does, with no limit of 256 — and `feats` float32, the
posterior mean; plus our item's `id`, `item_index`, `resolution`, `center`, `scale` and
`downsample`, which SLat does not read and `decode` meshes it with), the folder's merged
`metadata.csv`, `normalization.json` (`{"mean": [...], "std": [...]}` per channel over every
latent token of the export: the object a config's `dataset.args.normalization` takes), our
record `.sparc3d-latents.json`, and the folder under `latent_key` in `data_dir.json`.
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
import shutil
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .data import DataError, Sample
from .loaded import Loaded
from .runtime import UsageError

#: The TRELLIS.2 commit whose loaders this layout was read from and checked against.
TRELLIS2_COMMIT = "5565d240c4a494caaf9ece7a554542b76ffa36d3"
#: `SLat`'s default `latent_key` (and the one `SLatShape` fixes): its `data_dir` key and the
#: prefix of its metadata columns.
DEFAULT_LATENT_KEY = "shape_latent"
#: Our record of a latent folder (hidden, like `.sparc3d-export.json`).
LATENT_RECORD = ".sparc3d-latents.json"
#: The normalisation stats beside the latents.
STATS_FILE = "normalization.json"
#: The record `sparc3d export` leaves in an export folder.
EXPORT_RECORD = ".sparc3d-export.json"
#: A fixed time for the zip entries of an npz, so that equal arrays give equal bytes.
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)


@dataclass
class Export:
    """A `sparc3d export --format trellis2` folder, as its files describe it."""

    root: Path                    # the folder
    base: Path                    # data_dir.json's `base`: the path its folders are named under
    dataset: str                  # the key of its one dataset in data_dir.json
    data_dir: Dict[str, Any]      # data_dir.json as read
    grid: int                     # G of dual_grid_<G>
    items: List[Tuple[str, str]]  # (id, sha256) in the export's order
    fingerprint: str              # the exported job's fingerprint


def read_export(root: Path) -> Export:
    """The export at `root`; a UsageError naming the file when it is no TRELLIS.2 export."""
    root = Path(root)
    record = _read_json(root / EXPORT_RECORD, "not a sparc3d export (run `sparc3d export JOB "
                        "--format trellis2 --out DIR` first)")
    if record.get("format") != "trellis2":
        raise UsageError(f"{root / EXPORT_RECORD}: an export of format {record.get('format')!r}, "
                         "not trellis2")
    data_dir = _read_json(root / "data_dir.json", "an export without data_dir.json")
    if len(data_dir) != 1:
        raise UsageError(f"{root / 'data_dir.json'}: {len(data_dir)} datasets, expected one")
    (dataset, folders), = data_dir.items()
    if "base" not in folders or "dual_grid" not in folders:
        raise UsageError(f"{root / 'data_dir.json'}: no `base` or `dual_grid` folder listed")
    grid = Path(folders["dual_grid"]).name
    if not grid.startswith("dual_grid_") or not grid[len("dual_grid_"):].isdigit():
        raise UsageError(f"{root / 'data_dir.json'}: dual_grid {folders['dual_grid']!r} is not "
                         "a dual_grid_<G> folder")
    return Export(root, Path(folders["base"]), dataset, data_dir,
                  int(grid[len("dual_grid_"):]), _export_items(root),
                  str(record.get("fingerprint", "")))


def _read_json(path: Path, missing: str) -> Dict[str, Any]:
    """A JSON object from `path`; a UsageError saying `missing` when there is none."""
    try:
        value = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UsageError(f"{path.parent}: {missing} (no {path.name})") from None
    except (OSError, ValueError) as e:
        raise UsageError(f"{path}: unreadable ({e})") from None
    if not isinstance(value, dict):
        raise UsageError(f"{path}: not a JSON object")
    return value


def _export_items(root: Path) -> List[Tuple[str, str]]:
    """(id, sha256) of every row of the export's root `metadata.csv`, which names each item's
    files by its source sha256 (docs/FORMAT.md, "TRELLIS.2's dual grid dataset")."""
    path = root / "metadata.csv"
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
    except FileNotFoundError:
        raise UsageError(f"{root}: an export without metadata.csv") from None
    items = []
    for n, r in enumerate(rows, start=2):
        sha, item_id = (r.get("sha256") or "").strip(), r.get("id")
        if not sha or item_id is None:
            raise UsageError(f"{path} line {n}: no sha256 or id for item {item_id!r}")
        items.append((item_id, sha))
    return items


def job_fingerprints(data: Sequence[str]) -> List[str]:
    """The fingerprints of the jobs among `data` (folders with a job.json)."""
    out = []
    for d in data:
        job = Path(d) / "job.json"
        if job.is_file():
            out.append(str(json.loads(job.read_text(encoding="utf-8")).get("fingerprint", "")))
    return out


# --- Writing ------------------------------------------------------------------------------------

def write_npz(path: Path, arrays: Dict[str, np.ndarray]) -> None:
    """An npz (deflated, as `np.savez_compressed`) whose bytes depend on the arrays alone: every
    entry carries the same fixed time. Written to a temporary name and renamed."""
    tmp = path.with_name(path.name + ".tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        for name, a in arrays.items():
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.asanyarray(a), allow_pickle=False)
            info = zipfile.ZipInfo(name + ".npy", date_time=_ZIP_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            z.writestr(info, buf.getvalue(), compresslevel=6)
    os.replace(tmp, path)


def latent_arrays(s: Sample, lat: Dict[str, np.ndarray], downsample: int) -> Dict[str, np.ndarray]:
    """The npz of one item: SLat's `coords` and `feats`, then what our `decode` needs."""
    return {"coords": lat["coords"].astype(np.int32), "feats": lat["mean"].astype(np.float32),
            "id": np.array(s.id), "item_index": np.array(int(s.meta["item_index"]), np.int64),
            "resolution": np.array(int(s.meta["resolution"]), np.int64),
            "center": np.asarray(s.meta["center"], np.float64),
            "scale": np.array(float(s.meta["scale"]), np.float64),
            "downsample": np.array(downsample, np.int64)}


class Moments:
    """Per-channel mean and variance over the rows of many arrays, merged item by item (Chan et
    al.'s pairwise update, in float64), so that the result does not depend on a running sum of
    squares' cancellation."""

    def __init__(self) -> None:
        self.n = 0
        self.mean: Optional[np.ndarray] = None
        self.m2: Optional[np.ndarray] = None

    def add(self, x: np.ndarray) -> None:
        """Adds the rows of `x` [n, C]."""
        x = x.astype(np.float64)
        n, mean = len(x), x.mean(axis=0)
        m2 = ((x - mean) ** 2).sum(axis=0)
        if self.mean is None:
            self.n, self.mean, self.m2 = n, mean, m2
            return
        total = self.n + n
        delta = mean - self.mean
        self.mean = self.mean + delta * (n / total)
        self.m2 = self.m2 + m2 + delta ** 2 * (self.n * n / total)
        self.n = total

    def stats(self) -> Dict[str, List[float]]:
        """`{"mean": [...], "std": [...]}`: the population standard deviation; a channel that
        never varies gets std 1 (dividing by 0 would make every value infinite)."""
        std = np.sqrt(self.m2 / self.n)
        std = np.where(std > 0, std, 1.0)
        return {"mean": [float(v) for v in self.mean], "std": [float(v) for v in std]}


@dataclass
class Plan:
    """Where one `encode --format trellis2` writes, and what it encodes."""

    export: Export
    key: str
    name: str
    folder: Path      # <export>/<key>s/<name>
    listed: Path      # the same folder under data_dir.json's base
    todo: List[Tuple[int, str, str]]  # (sample index, id, sha256)
    not_exported: int  # ok items of the jobs that are not in the export


def plan(export: Export, samples, data: Sequence[str], key: str, name: str) -> Plan:
    """Matches the export's items to the jobs' samples by id; refuses an export of another job
    or one naming an item the jobs do not hold (ok), and a folder that is not ours."""
    _check_names(key, name)
    prints = job_fingerprints(data)
    if prints and export.fingerprint not in prints:
        raise UsageError(f"{export.root}: exported from a job of fingerprint {export.fingerprint}, "
                         f"not from {', '.join(data)} ({', '.join(prints)}): encode the job it "
                         "was exported from")
    index = {item_id: i for i, item_id in enumerate(samples.ids)}
    todo = []
    for item_id, sha in export.items:
        if item_id not in index:
            raise UsageError(f"{export.root / 'metadata.csv'}: item {item_id!r} (sha256 {sha}) "
                             f"is no ok item of {', '.join(data)}")
        todo.append((index[item_id], item_id, sha))
    folder = export.root / f"{key}s" / name
    if folder.exists() and not (folder / LATENT_RECORD).is_file():
        raise UsageError(f"{folder} exists and holds no {LATENT_RECORD}: not ours, not replaced "
                         "(give another --latent-name)")
    return Plan(export, key, name, folder, export.base / f"{key}s" / name, todo,
                len(samples) - len(todo))


def _check_names(key: str, name: str) -> None:
    """A latent key is a Python-style name (a `data_dir` key and column prefix); a latent name
    one folder name."""
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", key):
        raise UsageError(f"--latent-key {key!r}: expected letters, digits and _ (e.g. "
                         f"{DEFAULT_LATENT_KEY})")
    if not re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9._-]*", name):
        raise UsageError(f"--latent-name {name!r}: expected one folder name of letters, digits, "
                         "'.', '_' and '-', not starting with '.' or '-'")


def encode_item(loaded: Loaded, s: Sample) -> Dict[str, np.ndarray]:
    """One item's latent (alone in its forward pass, as TRELLIS.2's toolkit encodes, so that its
    bytes do not depend on the other items); a UsageError when it does not fit the budget or
    its latent is not finite."""
    why = loaded.too_large(s)
    if why:
        raise UsageError(why)
    lat = loaded.encode([s])[0]
    if not np.isfinite(lat["mean"]).all():
        raise UsageError(f"item {s.id!r}: non-finite latent")
    return lat


def encode(ckpt: Path, data: Sequence[str], export_dir: Path, device: str,
           max_cells: Optional[int] = None, key: str = DEFAULT_LATENT_KEY,
           name: Optional[str] = None) -> Dict[str, Any]:
    """`encode --format trellis2`: the latents of every item of the export at `export_dir`
    (matched to the jobs' items by id) written into it in TRELLIS.2's layout (module doc), with
    their metadata, their normalisation stats and `data_dir.json`'s entry. An item that fails
    (too large, unreadable, non-finite) is left out, named in the summary's `failed`; the
    others go on."""
    loaded = Loaded(ckpt, device, max_cells)
    samples = loaded.load_samples(data)
    export = read_export(export_dir)
    p = plan(export, samples, data, key, name or f"sparc3d_vae_{loaded.digest}_{export.grid}")
    stage = _clear_debris(p.folder)
    stage.mkdir(parents=True)
    rows, failed, moments, res = [], [], Moments(), 0
    for i, item_id, sha in p.todo:
        try:
            s = samples[i]
            lat = encode_item(loaded, s)
        except (UsageError, DataError) as e:
            failed.append({"id": item_id, "sha256": sha, "error": str(e)})
            continue
        write_npz(stage / f"{sha}.npz", latent_arrays(s, lat, loaded.cfg.model.downsample))
        rows.append((sha, len(lat["coords"])))
        moments.add(lat["mean"])
        res = max(res, int(s.meta["resolution"]))
    if not rows:
        shutil.rmtree(stage)
        raise UsageError(f"{export.root}: no item encoded"
                         + (f" ({failed[0]['error']})" if failed else " (the export lists none)"))
    stats = moments.stats()
    grid = -(-res // loaded.cfg.model.downsample)  # the latent grid: ceil(N / downsample)
    _write_listing(stage, p, rows, stats, _record(loaded, p, rows, failed, res))
    _swap_in(stage, p.folder)
    _list_in_data_dir(export, key, p.listed)
    return {"items": len(rows), "failed": failed, "not_exported": p.not_exported,
            "folder": str(p.folder), "latent_key": key, "latent_grid": grid,
            "latent_channels": loaded.cfg.model.latent_channels,
            "tokens_mean": float(np.mean([n for _, n in rows])), "normalization": stats}


def _record(loaded: Loaded, p: Plan, rows, failed, resolution: int) -> Dict[str, Any]:
    """Our record of a latent folder: what made it and the values a TRELLIS.2 config needs."""
    c = loaded.cfg.model
    return {"format": "trellis2-latents", "trellis2_commit": TRELLIS2_COMMIT,
            "checkpoint": loaded.digest, "latent_key": p.key, "latent_name": p.name,
            "export_fingerprint": p.export.fingerprint, "dual_grid": p.export.grid,
            "latent_channels": c.latent_channels, "downsample": c.downsample,
            "resolution": resolution, "latent_grid": -(-resolution // c.downsample),
            "items": len(rows), "tokens": int(sum(n for _, n in rows)),
            "feats": "posterior mean", "failed": failed}


def _write_listing(stage: Path, p: Plan, rows, stats, record) -> None:
    """The folder's `metadata.csv` (what `update_metadata` would merge from the toolkit's
    records), `normalization.json` and our record."""
    with open(stage / "metadata.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["sha256", f"{p.key}_encoded", f"{p.key}_tokens"])
        w.writerows([sha, "True", n] for sha, n in rows)
    (stage / STATS_FILE).write_text(json.dumps(stats, indent=2) + "\n")
    (stage / LATENT_RECORD).write_text(json.dumps(record, indent=2) + "\n")


def _clear_debris(folder: Path) -> Path:
    """Removes what killed runs left beside `folder` (`.NAME.partial-PID`, `.NAME.old-PID`) and
    returns this run's staging folder."""
    if folder.parent.is_dir():
        for left in folder.parent.glob(f".{folder.name}.*-*"):
            if left.name.rsplit("-", 1)[0] in (f".{folder.name}.partial", f".{folder.name}.old"):
                shutil.rmtree(left, ignore_errors=True)
    return folder.with_name(f".{folder.name}.partial-{os.getpid()}")


def _swap_in(stage: Path, folder: Path) -> None:
    """Moves the finished folder into place, the earlier one (ours) aside and then away."""
    old = folder.with_name(f".{folder.name}.old-{os.getpid()}")
    if folder.exists():
        os.replace(folder, old)
    os.replace(stage, folder)
    shutil.rmtree(old, ignore_errors=True)


def _list_in_data_dir(export: Export, key: str, listed: Path) -> None:
    """Names the latent folder under `key` in the export's `data_dir.json` (the other entries
    as they are), written to a temporary name and renamed."""
    data_dir = json.loads(json.dumps(export.data_dir))
    data_dir[export.dataset][key] = str(listed)
    path = export.root / "data_dir.json"
    tmp = path.with_name(path.name + ".tmp")
    # As `sparc3d export` writes it (serde_json's pretty printer: sorted keys, 2 spaces).
    tmp.write_text(json.dumps(data_dir, indent=2, sort_keys=True, ensure_ascii=False),
                   encoding="utf-8")
    os.replace(tmp, path)


# --- Reading back ---------------------------------------------------------------------------------

def is_npz_latents(path: Path) -> bool:
    """Whether `decode --latents` names npz latents (a file, or a folder holding them) rather
    than Parquet latent shards; the export folder itself is refused, naming its latent
    folders."""
    path = Path(path)
    if (path / "data_dir.json").is_file():
        listed = "; ".join(_latent_folders(path)) or (
            "none listed in data_dir.json yet: run `sparc3d-vae encode --format trellis2`")
        raise UsageError(f"{path} is a TRELLIS.2 export: give --latents its latent folder "
                         f"({listed})")
    return path.suffix == ".npz" or (path.is_dir() and any(path.glob("*.npz")))


def _latent_folders(export: Path) -> List[str]:
    """`key: folder` of every `*_latent` entry of an export's data_dir.json."""
    data_dir = _read_json(export / "data_dir.json", "an export without data_dir.json")
    return [f"{k}: {v}" for folders in data_dir.values() if isinstance(folders, dict)
            for k, v in folders.items() if k.endswith("latent")]


def read_stats(path: Path, channels: int) -> Tuple[np.ndarray, np.ndarray]:
    """(mean, std) float32 [C] from a `normalization.json`, checked against the channels."""
    stats = _read_json(Path(path), "no normalisation stats")
    try:
        mean = np.asarray(stats["mean"], np.float32).reshape(-1)
        std = np.asarray(stats["std"], np.float32).reshape(-1)
    except (KeyError, TypeError, ValueError) as e:
        raise UsageError(f"{path}: no `mean` and `std` lists of numbers ({e})") from None
    if len(mean) != channels or len(std) != channels:
        raise UsageError(f"{path}: {len(mean)} means and {len(std)} stds, the checkpoint has "
                         f"{channels} latent channels")
    return mean, std


def npz_row(path: Path, loaded: Loaded, stats: Optional[Tuple[np.ndarray, np.ndarray]],
            resolution: Optional[int]) -> Dict[str, Any]:
    """A latent row for `decode` from one npz: ours (with the item's frame) or a bare
    `coords` / `feats` pair (a flow's sample: `resolution` needed, the mesh in the grid's
    [−0.5, 0.5] frame); feats un-normalised with `stats` (`feats · std + mean`, as TRELLIS.2's
    `SLatVisMixin.decode_latent` does) when given. A UsageError names the file."""
    try:
        with np.load(path, allow_pickle=False) as z:
            a = {k: z[k] for k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile) as e:
        raise UsageError(f"{path}: not a readable npz ({e})") from None
    coords, feats = _checked_pair(path, a, loaded.cfg.model.latent_channels)
    if "downsample" in a and int(a["downsample"]) != loaded.cfg.model.downsample:
        raise UsageError(f"{path}: encoded with downsample {int(a['downsample'])}, the "
                         f"checkpoint uses {loaded.cfg.model.downsample}")
    if stats is not None:
        feats = feats * stats[1] + stats[0]
    n = int(a["resolution"]) if "resolution" in a else resolution
    if n is None:
        raise UsageError(f"{path}: no `resolution` in the file (a bare sample): give "
                         "--resolution N, the grid of the job it was encoded from (`resolution` "
                         f"in the latent folder's {LATENT_RECORD})")
    center = a["center"].astype(np.float64) if "center" in a else np.zeros(3)
    return {"id": str(a["id"]) if "id" in a else path.stem, "coords": coords,
            "mean": feats.astype(np.float32), "resolution": n,
            "scale": float(a["scale"]) if "scale" in a else 1.0,
            "center_x": float(center[0]), "center_y": float(center[1]),
            "center_z": float(center[2])}


def _checked_pair(path: Path, a: Dict[str, np.ndarray], channels: int):
    """`coords` int32 [n, 3] (non-negative) and `feats` float32 [n, C] (finite) of an npz."""
    if "coords" not in a or "feats" not in a:
        raise UsageError(f"{path}: no `coords` and `feats` arrays (it has {sorted(a)})")
    coords, feats = a["coords"], a["feats"]
    if coords.ndim != 2 or coords.shape[1] != 3 or not np.issubdtype(coords.dtype, np.integer) \
            or (coords < 0).any():
        raise UsageError(f"{path}: coords {coords.dtype} {list(coords.shape)}, expected "
                         "non-negative integers [n, 3]")
    if feats.shape != (len(coords), channels):
        raise UsageError(f"{path}: feats {list(feats.shape)}, the checkpoint expects "
                         f"[{len(coords)}, {channels}]")
    if not np.isfinite(feats).all():
        raise UsageError(f"{path}: non-finite feats")
    return coords.astype(np.int32), feats.astype(np.float32)


def npz_paths(latents: Path, ids: Optional[List[str]]) -> List[Path]:
    """The npz files `decode` reads: the file itself, or the folder's `*.npz` (sorted); with
    `ids`, those whose stem (sha256) or `id` inside is one of them, in that order."""
    latents = Path(latents)
    if latents.suffix == ".npz":
        if not latents.is_file():
            raise UsageError(f"{latents}: no such npz")
        return [latents]
    paths = sorted(latents.glob("*.npz"))
    if ids is None:
        return paths
    by = {}
    for p in paths:
        by.setdefault(p.stem, p)
        try:
            with np.load(p, allow_pickle=False) as z:
                if "id" in z.files:
                    by.setdefault(str(z["id"]), p)
        except (OSError, ValueError, zipfile.BadZipFile):
            continue  # read again (and reported) when decoded, if asked for
    missing = [i for i in ids if i not in by]
    if missing:
        raise UsageError(f"{latents}: no latent npz for id or sha256 {missing[0]!r}")
    return [by[i] for i in ids]
