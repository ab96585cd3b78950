"""Decoded cubes to meshes: the cubes go to the Rust extractor through a tensor file
(`sparc3d extract --close`). `decode` meshes latents (Parquet shards, or npz in TRELLIS.2's
layout), `reconstruct` one item of a job (encode → decode → extract); an item that fails gets
an `error` in its summary and the others go on.
"""

from __future__ import annotations

import re
import tempfile
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

from .data import Cubes, Sample, cubes_row, write_cubes
from . import trellis2_latents as t2
from .latents import read_latents
from .loaded import Loaded
from .runtime import UsageError, find_sparc3d, run_sparc3d


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


def _extract_decoded(binary: str, cubes_file: Path, item_id: str, cubes: Cubes, mesh: Path,
                     fill_holes: bool) -> Dict[str, Any]:
    """`extract` of one decoded item; a UsageError when the decoder kept no cell with a surface."""
    if len(cubes.cells) == 0:
        raise UsageError(f"item {item_id!r}: the decoder kept no cell with a surface")
    return extract(binary, cubes_file, item_id, mesh, fill_holes)


def decode(ckpt: Path, latents: Path, ids: Optional[List[str]], out: Path, device: str,
           fill_holes: bool, sparc3d: Optional[str], max_cells: Optional[int] = None,
           normalized_by: Optional[Path] = None,
           resolution: Optional[int] = None) -> List[Dict[str, Any]]:
    """Decodes latents (of `ids`, or all) to meshes `out/<id>.ply` through `sparc3d extract`:
    Parquet latent shards of `encode`, or npz latents in TRELLIS.2's layout (`encode --format
    trellis2`, or a flow's sample; `normalized_by` un-normalises them, `resolution` gives a
    bare sample its grid: `trellis2_latents.npz_row`). An item that fails gets an `error` in
    its summary and the others go on."""
    binary = find_sparc3d(sparc3d)
    loaded = Loaded(ckpt, device, max_cells)
    if t2.is_npz_latents(latents):
        entries = _npz_entries(latents, ids, loaded, normalized_by, resolution)
        per_pass = 1  # one item per pass, as `encode --format trellis2` and `reconstruct`
    else:
        if normalized_by is not None or resolution is not None:
            raise UsageError(f"{latents}: --normalized-by and --resolution are for npz latents "
                             "(TRELLIS.2's layout); Parquet latents carry their item's frame "
                             "and are not normalised")
        entries = read_latents(latents, ids, loaded)
        per_pass = loaded.cfg.train.batch_size
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rows = [e for e in entries if "error" not in e]
    meshed = iter(_decode_rows(loaded, binary, rows, out, fill_holes, per_pass))
    return [e if "error" in e else next(meshed) for e in entries]


def _npz_entries(latents: Path, ids: Optional[List[str]], loaded: Loaded,
                 normalized_by: Optional[Path], resolution: Optional[int]) -> List[Dict[str, Any]]:
    """A latent row per npz, or `{"id", "error"}` for a file that cannot be decoded."""
    stats = (t2.read_stats(normalized_by, loaded.cfg.model.latent_channels)
             if normalized_by is not None else None)
    entries = []
    for path in t2.npz_paths(latents, ids):
        try:
            entries.append(t2.npz_row(path, loaded, stats, resolution))
        except UsageError as e:  # one bad file does not stop the others
            entries.append({"id": path.stem, "error": str(e)})
    return entries


def _decode_rows(loaded: Loaded, binary: str, rows: Sequence[Dict[str, Any]], out: Path,
                 fill_holes: bool, per_pass: int) -> List[Dict[str, Any]]:
    """Latent rows (`coords`, `mean` and the item's frame) decoded `per_pass` at a time and
    meshed to `out/<id>.ply`; one summary per row, in order."""
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for start in range(0, len(rows), per_pass):
            chunk = rows[start:start + per_pass]
            cubes = loaded.decode(chunk)
            file = Path(tmp) / f"cubes-{start}.parquet"
            meta = [{"resolution": r["resolution"], "scale": r["scale"],
                     "center": [r["center_x"], r["center_y"], r["center_z"]]} for r in chunk]
            write_cubes(file, [cubes_row(r["id"], m, c) for r, m, c in zip(chunk, meta, cubes)])
            for r, c in zip(chunk, cubes):
                mesh = out / f"{safe_name(r['id'])}.ply"
                try:
                    results.append({"id": r["id"],
                                    **_extract_decoded(binary, file, r["id"], c, mesh, fill_holes)})
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
        summary.update(_extract_decoded(binary, file, s.id, c, mesh, fill_holes))
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
    samples = loaded.load_samples(data)
    s = samples[samples.index_of(item_id)]
    result = reconstruct_items(loaded, [s], binary, [Path(out)], fill_holes, keep_tensors)[0]
    if "error" in result:
        raise UsageError(result["error"])
    return result
