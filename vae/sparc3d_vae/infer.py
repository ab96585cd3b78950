"""`encode`, `decode`, `reconstruct`, `evaluate`: a trained VAE applied to jobs and latents.

Latents are Parquet shards `LATENTS/part-NNNNN.parquet` (with a `part-NNNNN.complete.json`),
one row per item: `id`, `item_index`, `uri`, `resolution`, `center_x/y/z`, `scale`,
`downsample`, and the tensors `coords` (int32 [n, 3], latent grid), `mean` and `logvar`
(float32 [n, C]) in the shards' tensor encoding, so `sparc3d_reader.iter_tensor_rows` reads
them. Decoded cubes go to the Rust extractor through a tensor file (`sparc3d extract`).
"""

from __future__ import annotations

import hashlib
import json
import re
import statistics
import struct
import sys
import tempfile
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, Iterator, List, Optional, Sequence, Tuple

import numpy as np
import pyarrow as pa
import torch

import sparc3d_reader as reader

from .data import (Cubes, DataError, Sample, Samples, corners_to_cubes, cubes_row, job_info,
                   make_batch, write_cubes)
from .runtime import (UsageError, autocast, checkpoint_path, find_sparc3d, load_checkpoint,
                      memory_guard, model_from_checkpoint, pick_device, run_sparc3d)
from .sparse import SparseTensor

LATENT_TENSORS = ("coords", "mean", "logvar")
LATENT_SCHEMA = {"id": pa.string(), "item_index": pa.uint64(), "uri": pa.string(),
                 "resolution": pa.uint32(), "center_x": pa.float64(), "center_y": pa.float64(),
                 "center_z": pa.float64(), "scale": pa.float64(), "downsample": pa.uint32()}
#: Items per latent shard.
LATENT_SHARD_SIZE = 256


class Loaded:
    """A checkpoint ready to run: config, model, device, and its limits."""

    def __init__(self, ckpt: Path, device_name: str, max_cells: Optional[int] = None):
        self.path = checkpoint_path(ckpt)
        state = load_checkpoint(self.path)
        self.device = pick_device(device_name)
        self.cfg, self.model = model_from_checkpoint(state, self.device, str(self.path))
        if max_cells is not None and max_cells < 1:
            raise UsageError(f"--max-cells {max_cells}: must be a positive number of cells")
        # Cells per forward pass: the training budget unless asked (inference keeps no
        # gradients, so a model runs on grids finer than it trained on with a larger one).
        self.max_cells = max_cells or self.cfg.train.max_cells_per_batch
        self.budget_note = ("--max-cells" if max_cells else
                            f"train.max_cells_per_batch of {self.path}; raise it with --max-cells")
        self.digest = hashlib.sha256(self.path.read_bytes()).hexdigest()[:16]
        if self.cfg.train.threads > 0 and self.device.type == "cpu":
            torch.set_num_threads(self.cfg.train.threads)

    def check_data(self, deformation: bool, source: str) -> None:
        """Refuses data whose kind (with or without δ) differs from what the model was trained on."""
        if deformation != self.cfg.model.deformation:
            raise UsageError(
                f"{source}: the data {'stores' if deformation else 'has no'} deformation, but "
                f"the checkpoint {self.path} was trained {'with' if self.cfg.model.deformation else 'without'} it")

    def too_large(self, s: Sample) -> Optional[str]:
        """Why an item cannot go through one forward pass, or None when it fits."""
        if len(s.cells) <= self.max_cells:
            return None
        return (f"item {s.id!r}: {len(s.cells)} cells, more than the {self.max_cells} cells "
                f"per forward pass ({self.budget_note})")

    def batches(self, samples: Sequence[Sample]) -> Iterator[List[Sample]]:
        """Samples grouped so that no group holds more than `max_cells` cells; an item larger
        than that alone is refused, naming it."""
        limit = self.max_cells
        group: List[Sample] = []
        cells = 0
        for s in samples:
            why = self.too_large(s)
            if why:
                raise DataError(why)
            if group and (cells + len(s.cells) > limit or len(group) >= self.cfg.train.batch_size):
                yield group
                group, cells = [], 0
            group.append(s)
            cells += len(s.cells)
        if group:
            yield group

    @torch.no_grad()
    def encode(self, samples: Sequence[Sample]) -> List[Dict[str, np.ndarray]]:
        """Latent mean / logvar of each sample: coords int32 [n, 3], mean, logvar float32 [n, C]."""
        x = make_batch(samples, self.device)
        what = f"encoding {', '.join(repr(s.id) for s in samples)}"
        with memory_guard(what, len(x.coords), self.max_cells, self.device, "--max-cells", ""), \
                autocast(self.device):
            mean, logvar, _ = self.model.encode(x)
        out = []
        for b in range(len(samples)):
            rows = mean.coords[:, 0] == b
            out.append({"coords": mean.coords[rows, 1:].cpu().numpy().astype(np.int32),
                        "mean": mean.feats[rows].float().cpu().numpy(),
                        "logvar": logvar[rows].float().cpu().numpy()})
        return out

    @torch.no_grad()
    def decode(self, latents: Sequence[Dict[str, np.ndarray]]) -> List[Cubes]:
        """Sparse cubes decoded from latents (the mean), pruned by the predicted occupancy."""
        coords = np.concatenate([np.concatenate([np.full((len(l["coords"]), 1), b, np.int32),
                                                 l["coords"].astype(np.int32)], 1)
                                 for b, l in enumerate(latents)])
        feats = np.concatenate([l["mean"].astype(np.float32) for l in latents])
        z = SparseTensor.build(torch.from_numpy(coords).to(self.device),
                               torch.from_numpy(feats).to(self.device),
                               level=self.cfg.model.levels(), batch_size=len(latents))
        limit = self.max_cells
        what = f"decoding {len(latents)} latent(s), at most 8× the budget"
        with memory_guard(what, 8 * limit, limit, self.device, "--max-cells", ""), autocast(self.device):
            dec = self.model.decoder(z, None, max_voxels=limit * 8)
        return corners_to_cubes(dec.cells, dec.sign_logits, dec.magnitude, dec.delta)


def _latent_row(s: Sample, lat: Dict[str, np.ndarray], downsample: int) -> Dict[str, Any]:
    c = [float(v) for v in s.meta["center"]]
    return {"id": s.id, "item_index": int(s.meta["item_index"]), "uri": s.meta["uri"],
            "resolution": int(s.meta["resolution"]), "center_x": c[0], "center_y": c[1],
            "center_z": c[2], "scale": float(s.meta["scale"]), "downsample": downsample, **lat}


def _load_samples(data: Sequence[str], loaded: Loaded) -> Samples:
    info = job_info(data)
    loaded.check_data(info.deformation, ", ".join(data))
    return Samples(info, cache=False)


def encode(ckpt: Path, data: Sequence[str], out: Path, device: str,
           max_cells: Optional[int] = None) -> Dict[str, Any]:
    """Writes the latents of every ok item of the jobs to `out` as Parquet shards."""
    loaded = Loaded(ckpt, device, max_cells)
    samples = _load_samples(data, loaded)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    meta = {"sparc3d.kind": "latents", "sparc3d_vae.checkpoint": loaded.digest,
            "sparc3d_vae.config": json.dumps(loaded.cfg.to_dict(), sort_keys=True)}
    rows: List[Dict[str, Any]] = []
    shard = 0
    voxels: List[int] = []

    def flush() -> None:
        nonlocal rows, shard
        path = out / f"part-{shard:05d}.parquet"
        reader.write_tensor_file(path, rows, LATENT_TENSORS, meta, LATENT_SCHEMA)
        reader.write_completion_record(
            path, {"shard": shard, "rows": len(rows), "checkpoint": loaded.digest})
        rows, shard = [], shard + 1

    items = (samples[i] for i in range(len(samples)))
    for group in loaded.batches(items):
        for s, lat in zip(group, loaded.encode(group)):
            rows.append(_latent_row(s, lat, loaded.cfg.model.downsample))
            voxels.append(len(lat["coords"]))
            if len(rows) == LATENT_SHARD_SIZE:
                flush()
    if rows:
        flush()
    return {"items": len(voxels), "shards": shard,
            "latent_voxels_mean": float(np.mean(voxels)) if voxels else 0.0,
            "latent_channels": loaded.cfg.model.latent_channels}


def safe_name(item_id: str) -> str:
    """A file name for an item id (ids are free text)."""
    name = re.sub(r"[^A-Za-z0-9._-]", "_", item_id)[:100]
    return name if name.strip("._") else "item"


def extract(binary: str, cubes_file: Path, item_id: str, out: Path, fill_holes: bool) -> Dict[str, Any]:
    """`sparc3d extract --close` of one item of a tensor file (a decoded grid may end where the
    surface does not; closing gives every grid vertex a sign, so the mesh is closed); its JSON
    summary."""
    args = ["extract", cubes_file, "--id", item_id, "-o", out, "--close"]
    if fill_holes:
        args.append("--fill-holes")
    return run_sparc3d(binary, *args)


def reported_pieces(summary: Dict[str, Any], mesh: Path) -> int:
    """The pieces (triangles connected through shared vertices) of a mesh `sparc3d extract`
    wrote, from its summary: the binary's topology report, not a count of our own."""
    if "components" not in summary:
        raise UsageError(f"sparc3d extract reported no components for {mesh}: a sparc3d older "
                         "than this sparc3d-vae (rebuild it from the same checkout)")
    return int(summary["components"])


def within_20pct(pieces: int, reference: int) -> bool:
    """The issue's bar for pieces: within ±20 % of the reference's count."""
    return abs(pieces - reference) <= 0.2 * reference


def nearby_pieces(binary: str, source: Path, resolution: int) -> Dict[int, int]:
    """Pieces of `sparc3d convert` of the source (default settings) at N − 1, N and N + 1.

    A piece count that changes between neighbouring resolutions is a property of where the
    grid falls, not of the shape: a speck one grid vertex wide, or two parts under a voxel
    apart, is kept or lost by a shift of a fraction of a voxel (docs/VAE.md, "Pieces")."""
    counts = {}
    with tempfile.TemporaryDirectory() as tmp:
        for n in (resolution - 1, resolution, resolution + 1):
            out = run_sparc3d(binary, "convert", source, "-o", Path(tmp) / "near.ply", "--resolution", n)
            counts[n] = int(out["output_components"])
    return counts


def pieces_stable(nearby: Dict[int, int], resolution: int, stored: int) -> Optional[bool]:
    """Whether the converter's own piece count holds at N ± 1 (both within ±20 % of N's); None
    where its count at N differs from the stored Sparcubes mesh's (the job was converted with
    other settings, so the nearby counts say nothing about it)."""
    if nearby[resolution] != stored:
        return None
    return all(within_20pct(nearby[n], stored) for n in (resolution - 1, resolution + 1))


def _check_latents(rows: List[Dict[str, Any]], loaded: Loaded, source: str) -> None:
    c = loaded.cfg.model
    for r in rows:
        if r["mean"] is None or r["mean"].ndim != 2 or r["mean"].shape[1] != c.latent_channels:
            shape = None if r["mean"] is None else list(r["mean"].shape)
            raise UsageError(f"{source}: item {r['id']!r} has latents of shape {shape}, the "
                             f"checkpoint expects [n, {c.latent_channels}]")
        if int(r.get("downsample") or 0) != c.downsample:
            raise UsageError(f"{source}: item {r['id']!r} was encoded with downsample "
                             f"{r.get('downsample')}, the checkpoint uses {c.downsample}")


def decode(ckpt: Path, latents: Path, ids: Optional[List[str]], out: Path, device: str,
           fill_holes: bool, sparc3d: Optional[str], max_cells: Optional[int] = None) -> List[Dict[str, Any]]:
    """Decodes latents (of `ids`, or all) to meshes `out/<id>.ply` through `sparc3d extract`;
    an item that fails gets an `error` in its summary and the others go on."""
    binary = find_sparc3d(sparc3d)
    loaded = Loaded(ckpt, device, max_cells)
    try:
        rows = list(reader.iter_tensor_rows(latents, LATENT_TENSORS))
    except (FileNotFoundError, ValueError) as e:
        raise UsageError(str(e)) from None
    if ids is not None:
        by_id = {r["id"]: r for r in rows}
        missing = [i for i in ids if i not in by_id]
        if missing:
            raise UsageError(f"{latents}: no latents for id {missing[0]!r}")
        rows = [by_id[i] for i in ids]
    _check_latents(rows, loaded, str(latents))
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for start in range(0, len(rows), loaded.cfg.train.batch_size):
            chunk = rows[start:start + loaded.cfg.train.batch_size]
            cubes = loaded.decode(chunk)
            file = Path(tmp) / f"cubes-{start}.parquet"
            meta = [{"resolution": r["resolution"], "scale": r["scale"],
                     "center": [r["center_x"], r["center_y"], r["center_z"]]} for r in chunk]
            write_cubes(file, [cubes_row(r["id"], m, c) for r, m, c in zip(chunk, meta, cubes)])
            for r, c in zip(chunk, cubes):
                mesh = out / f"{safe_name(r['id'])}.ply"
                try:
                    if len(c.cells) == 0:
                        raise UsageError(f"item {r['id']!r}: the decoder kept no cell with a surface")
                    results.append({"id": r["id"], **extract(binary, file, r["id"], mesh, fill_holes)})
                except UsageError as e:  # one bad item does not stop the others
                    results.append({"id": r["id"], "error": str(e)})
    return results


def reconstruct_items(loaded: Loaded, samples: Sequence[Sample], binary: str,
                      meshes: Sequence[Path], fill_holes: bool,
                      keep_tensors: Optional[Path] = None) -> List[Dict[str, Any]]:
    """Encode (the mean) → decode → extract, for samples; one extract summary each (in the
    samples' order, `meshes[i]` the mesh of `samples[i]`), with the latent size added. An item
    larger than the forward pass's budget, whose decoding holds no surface, or whose extraction
    fails gets an `error` instead of a mesh; the others go on."""
    results: List[Dict[str, Any]] = [{} for _ in samples]
    fits = []
    for i, s in enumerate(samples):
        why = loaded.too_large(s)
        if why:
            results[i] = {**_unmeshed(s), "error": why}
        else:
            fits.append(i)
    order = iter(fits)  # `batches` keeps the order of what it is given
    with tempfile.TemporaryDirectory() as tmp:
        for gi, group in enumerate(loaded.batches([samples[i] for i in fits])):
            lats = loaded.encode(group)
            cubes = loaded.decode(lats)
            file = keep_tensors if keep_tensors is not None else Path(tmp) / f"cubes-{gi}.parquet"
            write_cubes(file, [cubes_row(s.id, s.meta, c) for s, c in zip(group, cubes)])
            for s, lat, c in zip(group, lats, cubes):
                i = next(order)
                results[i] = _reconstructed(s, lat, c, binary, file, meshes[i], fill_holes)
    return results


def _unmeshed(s: Sample) -> Dict[str, Any]:
    """The summary of an item before (or without) its mesh: not watertight, nothing decoded."""
    return {"id": s.id, "watertight_before": False, "watertight": False, "latent_voxels": 0,
            "latent_floats": 0, "decoded_cells": 0, "true_cells": int(len(s.cells))}


def _reconstructed(s: Sample, lat: Dict[str, np.ndarray], c: Cubes, binary: str, file: Path,
                   mesh: Path, fill_holes: bool) -> Dict[str, Any]:
    """The summary of one decoded item: its extraction (or why there is none) and its sizes."""
    summary = _unmeshed(s)
    try:
        if len(c.cells) == 0:
            raise UsageError(f"item {s.id!r}: the decoder kept no cell with a surface")
        summary.update(extract(binary, file, s.id, mesh, fill_holes))
    except UsageError as e:
        summary["error"] = str(e)
    summary.update({"latent_voxels": int(len(lat["coords"])), "latent_floats": int(lat["mean"].size),
                    "decoded_cells": int(len(c.cells))})
    return summary


def reconstruct(ckpt: Path, data: Sequence[str], item_id: str, out: Path, device: str,
                fill_holes: bool, sparc3d: Optional[str], keep_tensors: Optional[Path],
                max_cells: Optional[int] = None) -> Dict[str, Any]:
    """One item of a job through the VAE and back to a mesh at `out`."""
    binary = find_sparc3d(sparc3d)
    loaded = Loaded(ckpt, device, max_cells)
    samples = _load_samples(data, loaded)
    s = samples[samples.index_of(item_id)]
    result = reconstruct_items(loaded, [s], binary, [Path(out)], fill_holes, keep_tensors)[0]
    if "error" in result:
        raise UsageError(result["error"])
    return result


def sample_key(seed: int, item_id: str) -> int:
    """The sampling key `sparc3d validate` and `sparc3d eval --sample` use (pipeline/src/sample.rs):
    the first 8 bytes, big-endian, of sha256(seed as 8 little-endian bytes ‖ id)."""
    d = hashlib.sha256(struct.pack("<Q", seed) + item_id.encode()).digest()
    return int.from_bytes(d[:8], "big")


def choose(ids: Iterable[str], k: int, seed: int) -> List[str]:
    """The k ids with the smallest (key, id): the same items as `sparc3d eval JOB --sample k`."""
    return [i for _, i in sorted((sample_key(seed, i), i) for i in ids)[:k]]


def _median(xs: List[float]) -> Optional[float]:
    return statistics.median(xs) if xs else None


def _mean(xs: List[float]) -> Optional[float]:
    return statistics.fmean(xs) if xs else None


def eval_samples(resolution: int) -> int:
    """Points `sparc3d eval` samples per mesh: its default 100,000 up to 128³; 1,000,000 from
    256³, where 100,000 points lie about 0.75 voxel apart and the CD and F1 measure mostly the
    sampling (docs/QUALITY.md, "Refinement against renderings"; docs/VAE.md, "256³ on CPU")."""
    return 100_000 if resolution <= 128 else 1_000_000


def evaluate(ckpt: Path, data: Sequence[str], sample: int, seed: int, out: Path, device: str,
             sparc3d: Optional[str], max_cells: Optional[int] = None,
             samples_per_mesh: Optional[int] = None) -> Dict[str, Any]:
    """Paper Table 2's metrics (CD, ANC, F1 via `sparc3d eval`) of reconstructions of a seeded
    sample of items against each item's Sparcubes mesh (and its source file when readable),
    and the share of watertight outputs before and after hole filling. Writes
    `out/summary.json`, `out/summary.md` and the meshes."""
    binary = find_sparc3d(sparc3d)
    loaded = Loaded(ckpt, device, max_cells)
    samples = _load_samples(data, loaded)
    chosen = choose(samples.ids, sample, seed)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    items = [samples[samples.index_of(i)] for i in chosen]
    meshes = [out / f"{safe_name(s.id)}.vae.ply" for s in items]
    recon = reconstruct_items(loaded, items, binary, meshes, fill_holes=True)
    rows = []
    for s, mesh, r in zip(items, meshes, recon):
        res = int(s.meta["resolution"])
        row = {"id": s.id, "uri": s.meta["uri"], "resolution": res,
               "watertight_before_fill": r["watertight_before"], "watertight": r["watertight"],
               "holes": r.get("holes", 0), "faces": r.get("faces", 0),
               "latent_voxels": r["latent_voxels"], "latent_floats": r["latent_floats"],
               "true_cells": r["true_cells"], "decoded_cells": r["decoded_cells"]}
        rows.append(row)
        if "error" in r:
            row["error"] = r["error"]
            print(f"{s.id}: {r['error']}", file=sys.stderr)
            continue
        i = samples.index_of(s.id)
        shard = samples.ds.paths[samples.ds.index[i][0]]
        ref = out / f"{safe_name(s.id)}.sparcubes.ply"
        ref_summary = run_sparc3d(binary, "extract", shard, "--id", s.id, "-o", ref)
        row["eval_samples"] = samples_per_mesh or eval_samples(res)
        counts = (reported_pieces(r, mesh), reported_pieces(ref_summary, ref))
        row.update(_measure(binary, mesh, ref, Path(s.meta["uri"]), res, row["eval_samples"], counts))
        print(f"{s.id}: CD {row['vs_sparcubes']['cd_voxels']:.3f} vox vs Sparcubes, "
              f"watertight {row['watertight_before_fill']} → {row['watertight']}", file=sys.stderr)
    summary = {"checkpoint": str(loaded.path), "data": list(data), "sample": len(rows),
               "seed": seed, "aggregate": _aggregate(rows), "items": rows}
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    (out / "summary.md").write_text(_markdown(summary))
    return summary


def _measure(binary: str, mesh: Path, ref: Path, src: Path, res: int, points: int,
             counts: Tuple[int, int]) -> Dict[str, Any]:
    """One reconstruction against its Sparcubes mesh, and both against the source when it is
    a readable file (the Sparcubes mesh is the floor the VAE cannot beat); the pieces of both
    (`counts`, as `sparc3d extract` reported them) and the converter's own at N ± 1."""
    ruler = ("--resolution", res, "--samples", points)
    row: Dict[str, Any] = {"vs_sparcubes": _metrics(run_sparc3d(binary, "eval", ref, mesh, *ruler)),
                           "components": counts[0], "sparcubes_components": counts[1]}
    if not src.is_file():
        return row
    try:
        row["vs_source"] = _metrics(run_sparc3d(binary, "eval", src, mesh, *ruler))
        row["sparcubes_vs_source"] = _metrics(run_sparc3d(binary, "eval", src, ref, *ruler))
    except UsageError as e:
        row["vs_source_error"] = str(e)
    try:
        nearby = nearby_pieces(binary, src, res)
        row["sparcubes_components_nearby"] = {str(n): c for n, c in nearby.items()}
        row["pieces_stable"] = pieces_stable(nearby, res, row["sparcubes_components"])
    except UsageError as e:
        row["nearby_error"] = str(e)
    return row


def _metrics(report: Dict[str, Any]) -> Dict[str, Any]:
    f1 = {f"f1@{f['threshold']}": f["f1"] for f in report.get("f1", [])}
    return {"cd_voxels": report["cd_voxels"], "cd": report["cd"], "anc": report["anc"], **f1}


def _aggregate(rows: List[Dict[str, Any]]) -> Dict[str, Any]:
    agg: Dict[str, Any] = {}
    if not rows:
        return agg
    n = len(rows)
    agg["failed"] = sum("error" in r for r in rows)
    agg["watertight_before_fill"] = sum(r["watertight_before_fill"] for r in rows) / n
    agg["watertight_after_fill"] = sum(r["watertight"] for r in rows) / n
    agg["latent_voxels_mean"] = _mean([r["latent_voxels"] for r in rows])
    agg["latent_floats_mean"] = _mean([r["latent_floats"] for r in rows])
    pieces = [r for r in rows if "components" in r]
    if pieces:
        agg.update(_pieces_aggregate(pieces))
    for against in ("vs_sparcubes", "vs_source", "sparcubes_vs_source"):
        have = [r[against] for r in rows if against in r]
        if not have:
            continue
        agg[against] = {k: {"mean": _mean([h[k] for h in have]), "median": _median([h[k] for h in have])}
                        for k in have[0]}
        agg[against]["items"] = len(have)
    return agg


def _miss(row: Dict[str, Any]) -> int:
    """+1 where an item has more pieces than the bar allows, −1 where fewer, 0 within it."""
    pieces, reference = row["components"], row["sparcubes_components"]
    if within_20pct(pieces, reference):
        return 0
    return 1 if pieces > reference else -1


def _pieces_aggregate(pieces: List[Dict[str, Any]]) -> Dict[str, Any]:
    """The issue's bar (the output's pieces within ±20 % of the Sparcubes mesh's) on every
    item and on the items whose count the converter itself keeps at N ± 1, and the bar applied
    to the converter against itself one resolution step away: what the count is worth as a
    target (docs/VAE.md, "Pieces")."""
    def share(items: List[Dict[str, Any]], key: Callable[[Dict[str, Any]], int]) -> Optional[float]:
        hits = sum(within_20pct(key(r), r["sparcubes_components"]) for r in items)
        return hits / len(items) if items else None

    stable = [r for r in pieces if r.get("pieces_stable")]
    agg: Dict[str, Any] = {
        "components_median": _median([r["components"] for r in pieces]),
        "sparcubes_components_median": _median([r["sparcubes_components"] for r in pieces]),
        "components_within_20pct": share(pieces, lambda r: r["components"]),
        "components_stable_items": len(stable),
        "components_within_20pct_stable": share(stable, lambda r: r["components"]),
        # Which way the stable items that miss the bar miss it: more pieces (a speck the
        # decoder adds) or fewer (a piece it loses); docs/VAE.md, "Pieces".
        "components_stable_more": sum(_miss(r) > 0 for r in stable),
        "components_stable_fewer": sum(_miss(r) < 0 for r in stable),
    }
    near = [r for r in pieces if r.get("pieces_stable") is not None]
    if near:
        agg["sparcubes_nearby_within_20pct"] = {
            side: share(near, lambda r, step=step: r["sparcubes_components_nearby"][str(r["resolution"] + step)])
            for side, step in (("n_minus_1", -1), ("n_plus_1", 1))}
    return agg


def _markdown(summary: Dict[str, Any]) -> str:
    agg = summary["aggregate"]
    lines = [f"# VAE reconstruction: {summary['sample']} items", "",
             f"checkpoint `{summary['checkpoint']}`, data {', '.join(summary['data'])}, seed {summary['seed']}", ""]
    if agg:
        lines += [f"- watertight before hole filling: {100 * agg['watertight_before_fill']:.0f}%, "
                  f"after: {100 * agg['watertight_after_fill']:.0f}%"
                  + (f" ({agg['failed']} items failed, counted as not watertight)" if agg["failed"] else ""),
                  f"- latent: {agg['latent_voxels_mean']:.1f} voxels, {agg['latent_floats_mean']:.0f} floats per shape (mean)"]
        if "components_median" in agg:
            lines.append(f"- pieces: median {agg['components_median']:g} (Sparcubes meshes: "
                         f"{agg['sparcubes_components_median']:g}); within ±20 % of the "
                         f"Sparcubes mesh's: {100 * agg['components_within_20pct']:.0f}% of items")
            if agg.get("components_within_20pct_stable") is not None:
                lines.append(f"- of the {agg['components_stable_items']} items whose piece count "
                             f"`sparc3d convert` keeps at N ± 1: "
                             f"{100 * agg['components_within_20pct_stable']:.0f}% within ±20 % "
                             f"(misses: {agg['components_stable_more']} with more pieces, "
                             f"{agg['components_stable_fewer']} with fewer)")
            if "sparcubes_nearby_within_20pct" in agg:
                near = agg["sparcubes_nearby_within_20pct"]
                lines.append(f"- the converter against itself: its pieces at N − 1 and N + 1 within "
                             f"±20 % of its own at N on {100 * near['n_minus_1']:.0f}% and "
                             f"{100 * near['n_plus_1']:.0f}% of items")
        lines.append("")
        titles = {"vs_sparcubes": "VAE output against the item's Sparcubes mesh",
                  "vs_source": "VAE output against the source mesh",
                  "sparcubes_vs_source": "Sparcubes mesh against the source mesh (the floor)"}
        for against, title in titles.items():
            if against in agg:
                a = agg[against]
                keys = [k for k in a if k != "items"]
                lines += [f"{title} ({a['items']} items):", "",
                          "| metric | mean | median |", "|---|---|---|"]
                lines += [f"| {k} | {a[k]['mean']:.4g} | {a[k]['median']:.4g} |" for k in keys]
                lines.append("")
    lines += ["| id | CD vs Sparcubes (vox) | ANC | watertight before → after fill | latent voxels |",
              "|---|---|---|---|---|"]
    for r in summary["items"]:
        if "error" in r:
            lines.append(f"| {r['id'][:16]} | failed: {r['error']} | | | {r['latent_voxels']} |")
            continue
        m = r["vs_sparcubes"]
        lines.append(f"| {r['id'][:16]} | {m['cd_voxels']:.3f} | {m['anc']:.1f} | "
                     f"{r['watertight_before_fill']} → {r['watertight']} | {r['latent_voxels']} |")
    return "\n".join(lines) + "\n"



