"""Reads sparc3d shards (docs/FORMAT.md) into per-item sparse cube tensors.

    from sparc3d_reader import iter_items, SparseCubesDataset, collate_sparse

    for item in iter_items("job"):             # a job folder, shard files, or a list of them
        item["coords"]        # int32 [K, 3]  active grid vertices (x, y, z) in 0..=resolution
        item["sdf"]           # float32 [K]   signed distance in voxels, negative inside
        item["deformation"]   # float32 [K, 3] displacement in voxels
        item["cells"]         # int32 [C, 3]  active cells by their minimum corner

    batch = collate_sparse([item_a, item_b])
    batch["coords"]           # int32 [K_a + K_b, 4]: batch index, x, y, z
    batch["feats"]            # float32 [K_a + K_b, 4]: sdf, dx, dy, dz
    batch["corners"]          # int64 [C_a + C_b, 8]: rows of each cell's 8 corners

Tensor files (the same encoding, other columns) are written with `write_tensor_file` and read
with `iter_tensor_rows`; `sparc3d extract` reads such a file, and `sparc3d-vae` writes its
latents with it.

Jobs with `[samples]` also give `item["samples"]` (vector-set VAE samples in the normalized
frame; `samples_to_source` maps them to the source frame), batched by `collate_vecset`. The
layouts of other codebases are written by `sparc3d export` (`run_export`) and read back with
`iter_export` / `ExportDataset` and `collate_direct3d_s2`, `collate_cubvh` (TRELLIS.2's export is
its own dataset folder, read by its `FlexiDualGridDataset`).

A job folder is read as the CLI reads it (`jobs.py`): only its own shards, each checked against
its completion record (`verify=True`: the sha256; "quick"; False) and its rows against the
frozen manifest; every shard left out is named in a `ShardWarning`. Wherever a job is taken, a
job URL is too (`s3://bucket/prefix`, `gs://`, `az://`: a job whose home is a bucket, read
through `pyarrow.fs` with the credentials and endpoint of the environment, `location.py`).

Only numpy and pyarrow are needed; `SparseCubesDataset` is a `torch.utils.data.Dataset` when
torch is installed (imported only when the class is first used) and a plain indexable class
otherwise.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import pathlib
from typing import Any, Dict, Iterable, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from . import jobs, location
from .jobs import ShardWarning, Verify
from .location import ObjectPath

__all__ = [
    "TENSORS",
    "SAMPLE_TENSORS",
    "ATTRIBUTE_TENSORS",
    "APPEARANCE_COLUMNS",
    "OPTIONAL_SAMPLE_TENSORS",
    "samples_to_source",
    "collate_vecset",
    "run_export",
    "CONSUMER_FORMATS",
    "iter_export",
    "ExportDataset",
    "collate_direct3d_s2",
    "collate_cubvh",
    "shard_paths",
    "ShardWarning",
    "decode_tensor",
    "row_to_item",
    "iter_items",
    "collate_sparse",
    "corner_index",
    "CORNER_OFFSETS",
    "encode_tensor",
    "write_completion_record",
    "write_tensor_file",
    "iter_tensor_rows",
    "shard_config",
    "check_schema_version",
    "SparseCubesDataset",
    "ObjectPath",
]

__version__ = "0.1.0"

#: Tensor columns and the dtype the reader returns them in.
TENSORS = {
    "coords": np.int32,
    "sdf": np.float32,
    "deformation": np.float32,
    "cells": np.int32,
}

#: Metadata columns copied into every item.
META_COLUMNS = ["item_index", "id", "uri", "status", "resolution",
                "center_x", "center_y", "center_z", "scale"]

#: Vector-set sample columns (docs/FORMAT.md, "Samples"), present when the job has `[samples]`;
#: the last ones, OPTIONAL_SAMPLE_TENSORS, only where the job draws that kind.
SAMPLE_TENSORS = ["surface_points", "surface_normals", "sharp_points", "sharp_normals",
                  "near_points", "near_sdf", "volume_points", "volume_sdf", "volume_occupancy",
                  "sharp_near_points", "sharp_near_sdf"]

#: Sample columns of kinds added later: absent from older shards, null in rows of jobs that
#: draw none of them (`sharp_near = 0`, every job from before the kind existed).
OPTIONAL_SAMPLE_TENSORS = ["sharp_near_points", "sharp_near_sdf"]

_READ_COLUMNS = META_COLUMNS + [f"{t}{s}" for t in TENSORS for s in ("", "_dtype", "_shape")]


def _columns_of(tensors: Iterable[str]) -> List[str]:
    return [f"{t}{s}" for t in tensors for s in ("", "_dtype", "_shape")]


#: Appearance per active cell (docs/FORMAT.md, "Attributes"), present when the job has
#: `[attributes] enabled = true`: one row per row of `cells`, uint8 (base colour sRGB [m, 3];
#: metallic, roughness, alpha [m], 0-255 for 0-1).
ATTRIBUTE_TENSORS = ["base_color", "metallic", "roughness", "alpha"]

#: The per-item facts stored beside the attributes (docs/FORMAT.md, "Attributes").
APPEARANCE_COLUMNS = ["materials", "textured", "textures", "texture_max_size", "alpha_modes",
                      "vertex_colors", "appearance_not_read", "attribute_nearest_cells"]

_SAMPLE_COLUMNS = _columns_of(t for t in SAMPLE_TENSORS if t not in OPTIONAL_SAMPLE_TENSORS)
_ATTRIBUTE_COLUMNS = _columns_of(ATTRIBUTE_TENSORS) + APPEARANCE_COLUMNS
_OPTIONAL_SAMPLE_COLUMNS = _columns_of(OPTIONAL_SAMPLE_TENSORS)

#: Prefix of the provenance columns: the manifest's own columns (licence, source, name, ...),
#: strings, null where an item's row had no value (docs/FORMAT.md, "Provenance columns").
PROVENANCE_PREFIX = "manifest."

#: A local path, or a job URL (`s3://bucket/prefix`, `gs://…`, `az://…`) where a job is taken.
PathLike = Union[str, os.PathLike, ObjectPath]


def shard_paths(paths: Union[PathLike, Iterable[PathLike]], complete_only: bool = True,
                verify: Verify = True) -> List[Union[pathlib.Path, ObjectPath]]:
    """The shard files under `paths` that the reader reads, checked as `iter_items` checks them
    (docs/RELIABILITY.md, "The Python reader"). Each path is a job folder (its own shards with a
    completion record that the file matches, and every row its item; with `complete_only`
    false also shards without a record), a folder of shard files, or a file (read when it has
    no completion record beside it), or a job URL (its shards' objects, as `ObjectPath`s whose
    `str` is their URL). Shards left out are named in a `ShardWarning`.

    `verify`: True hashes every shard against its record's sha256 (as `sparc3d inspect`), "quick"
    only those whose size or stamp changed since recorded (as `sparc3d status`), False checks
    the size only."""
    return [s.path for s in _shards(paths, complete_only) if _usable(s, verify)]


def _shards(paths: Union[PathLike, Iterable[PathLike]], complete_only: bool) -> List[jobs.Shard]:
    """The shards under `paths`, not yet checked against their records."""
    if isinstance(paths, (str, os.PathLike, ObjectPath)):
        paths = [paths]
    out: List[jobs.Shard] = []
    for p in paths:
        p = location.of(p)
        if isinstance(p, ObjectPath):
            out += jobs.job_shards(jobs.open_job(p), complete_only)
        elif p.is_dir():
            job = jobs.job_of_folder(p)
            out += jobs.job_shards(job, complete_only) if job else _folder_shards(p, complete_only)
        elif p.is_file():
            out.append(_file_shard(p))
        else:
            raise FileNotFoundError(f"{p}: neither a job folder nor a shard file")
    return out


def _record_beside(path: pathlib.Path) -> pathlib.Path:
    return path.with_name(path.name[: -len(".parquet")] + ".complete.json")


def _file_shard(path: pathlib.Path) -> jobs.Shard:
    """A file named on its own: a shard of a job (checked as the job's), or any other file."""
    job, index = jobs.job_of_file(path)
    record, torn = jobs.read_record(_record_beside(path)) if path.suffix == ".parquet" else (None, None)
    return jobs.Shard(path, job, index, record, torn=torn)


def _folder_shards(folder: pathlib.Path, complete_only: bool) -> List[jobs.Shard]:
    """`part-*.parquet` of a folder outside a job (or its `shards/`): those with a completion
    record (all with `complete_only` false); no job to check names or rows against."""
    shards = folder / "shards" if (folder / "shards").is_dir() else folder
    out = []
    for f in sorted(shards.glob("part-*.parquet")):
        record, torn = jobs.read_record(_record_beside(f))
        if record is not None or torn is not None or not complete_only:
            out.append(jobs.Shard(f, record=record, torn=torn))
    return out


def _usable(shard: jobs.Shard, verify: Verify) -> bool:
    """Whether a shard is read: it matches its completion record as far as `verify` looks,
    and a job's shard holds its items (`jobs.check_rows`). Otherwise a ShardWarning says why."""
    jobs.check_verify_mode(verify)
    why = shard.torn
    if why is None and shard.record is not None:
        why = jobs.check_against_record(shard, verify)
    if why is None and shard.job is not None:
        why = _rows_not_the_shards(shard)
    if why is None:
        return True
    fix = (f" `sparc3d verify {shard.job.root}` moves it aside, `sparc3d run {shard.job.root}` "
           "converts it again." if shard.job else "")
    jobs.warn_shards(f"{shard.path} is not read, its items left out: {why}.{fix}")
    return False


def _rows_not_the_shards(shard: jobs.Shard) -> Optional[str]:
    """Why a job shard's footer or rows are not its own (`jobs.check_rows`), if so; a file
    pyarrow cannot read is damaged too."""
    try:
        f = location.parquet_file(shard.path)
        return jobs.check_footer(shard, f) or jobs.check_rows(shard, jobs.read_check_columns(shard.path, f))
    except (OSError, pa.ArrowException, UnicodeDecodeError, OverflowError) as e:
        return f"it cannot be read ({type(e).__name__}: {e})"


#: The shard schema version this reader decodes (docs/FORMAT.md).
SCHEMA_VERSION = 3


def decode_tensor(row: Dict[str, Any], name: str) -> Optional[np.ndarray]:
    """Decodes one tensor column of a row as docs/FORMAT.md describes (None when absent): the
    zstd frame holds the elements' little-endian bytes in byte planes, column by column."""
    if row.get(name) is None:
        return None
    dtype, shape = _tensor_dtype(row, name), row[name + "_shape"]
    if not shape or any(d is None or d < 0 for d in shape):
        raise ValueError(f"item {row.get('id')!r}: column {name}_shape is {shape!r}, not a shape")
    n, k = int(shape[0]), int(np.prod(shape[1:]))
    raw = pa.decompress(row[name], decompressed_size=n * k * dtype.itemsize, codec="zstd")
    planes = np.frombuffer(raw, np.uint8).reshape(k, dtype.itemsize, n)
    return planes.transpose(2, 0, 1).copy().view(dtype).reshape(shape)


def _tensor_dtype(row: Dict[str, Any], name: str) -> np.dtype:
    """The numpy dtype of a tensor column; a ValueError naming the row and column unless it is
    a little-endian number type (a byte-order flip `<` → `>` would decode to other numbers)."""
    text = row[name + "_dtype"]
    try:
        dtype = np.dtype(text)
    except (TypeError, ValueError, SyntaxError):  # numpy parses some strings as Python
        dtype = None
    if dtype is None or str(text)[:1] not in ("<", "|") or dtype.kind not in "uif":
        raise ValueError(f"item {row.get('id')!r}: column {name}_dtype is {text!r}, not a "
                         "little-endian number type (docs/FORMAT.md, \"Tensor encoding\")")
    return dtype


def row_to_item(row: Dict[str, Any]) -> Dict[str, Any]:
    """One `ok` row (a dict of column values) as an item: metadata plus the tensors in the
    reader's dtypes (coords and cells int32 [K, 3], sdf float32 [K], deformation float32 [K, 3]).
    A ValueError names the columns the row lacks."""
    missing = [c for c in _READ_COLUMNS if c not in row]
    if missing:
        raise ValueError(f"item {row.get('id')!r}: no column {', '.join(map(repr, missing))} "
                         "(docs/FORMAT.md, \"Columns\")")
    item: Dict[str, Any] = {
        "id": row["id"],
        "item_index": int(row["item_index"]),
        "uri": row["uri"],
        "resolution": int(row["resolution"]),
        "center": np.array([row["center_x"], row["center_y"], row["center_z"]], dtype=np.float64),
        "scale": float(row["scale"]),
    }
    for name, dtype in TENSORS.items():
        t = decode_tensor(row, name)
        if t is None:
            raise ValueError(f"item {row['id']!r}: column {name!r} is empty")
        if name in ("coords", "deformation", "cells"):
            t = t.reshape(-1, 3)
        item[name] = t.astype(dtype, copy=True)
    provenance = {k[len(PROVENANCE_PREFIX):]: v for k, v in row.items()
                  if k.startswith(PROVENANCE_PREFIX)}
    if provenance:
        item["manifest"] = provenance
    if row.get("base_color") is not None:
        _add_attributes(item, row)
    if row.get("surface_points") is not None:
        item["samples"] = {name: decode_tensor(row, name) for name in SAMPLE_TENSORS
                           if name not in OPTIONAL_SAMPLE_TENSORS or row.get(name) is not None}
    return item


def _add_attributes(item: Dict[str, Any], row: Dict[str, Any]) -> None:
    """The attribute arrays (uint8, one row per row of `cells`) and the appearance facts."""
    m = len(item["cells"])
    for name in ATTRIBUTE_TENSORS:
        t = decode_tensor(row, name)
        t = t.reshape(-1, 3) if name == "base_color" else t.reshape(-1)
        if len(t) != m:
            raise ValueError(f"item {row['id']!r}: column {name!r} has {len(t)} rows, "
                             f"cells has {m}")
        item[name] = t.astype(np.uint8, copy=False)
    facts = {c: row.get(c) for c in APPEARANCE_COLUMNS}
    facts["alpha_modes"] = [x for x in (facts["alpha_modes"] or "").split(",") if x]
    facts["appearance_not_read"] = [x for x in (facts["appearance_not_read"] or "").split("\n") if x]
    item["appearance"] = facts


def samples_to_source(item: Dict[str, Any]) -> Dict[str, np.ndarray]:
    """The item's samples in the source mesh's frame (float32): points map as
    `source = p / (2 * scale) + center`, distances as `d / (2 * scale)`; normals and
    occupancy are unchanged."""
    s, center, scale = item["samples"], item["center"], item["scale"]
    out = {}
    for name, v in s.items():
        v = np.asarray(v)
        if name.endswith("_points"):
            out[name] = (v.astype(np.float64) / (2.0 * scale) + center).astype(np.float32)
        elif name.endswith("_sdf"):
            out[name] = (v.astype(np.float64) / (2.0 * scale)).astype(np.float32)
        else:
            out[name] = v.copy()
    return out


def collate_vecset(batch: Sequence[Dict[str, Any]], to_torch: bool = False) -> Dict[str, Any]:
    """Stacks the samples of items (dicts with `samples`, or the dicts `iter_export` yields for
    `vecset-npz`) into float32 arrays [B, n, ...]: `surface` [B, n, 6] (points + normals, as
    Hunyuan3D-2.1 and Dora feed their encoders), `sharp_surface` [B, m, 6], `near_points`
    [B, q, 3], `near_sdf` [B, q], `volume_points` [B, p, 3], `volume_sdf` [B, p],
    `volume_occupancy` [B, p], and where every item has them `sharp_near_points` [B, r, 3] and
    `sharp_near_sdf` [B, r]. Every item must have the same counts (a job's config fixes
    them; the sharp kinds are empty for a mesh without sharp edges, so they are stacked only
    when all items have the same number, else given as lists)."""
    def get(it, name):
        s = it["samples"] if "samples" in it else it
        return np.asarray(s[name])

    out: Dict[str, Any] = {}
    out["surface"] = np.stack([np.concatenate([get(it, "surface_points"), get(it, "surface_normals")], 1)
                               for it in batch]).astype(np.float32)
    sharp = [np.concatenate([get(it, "sharp_points"), get(it, "sharp_normals")], 1) for it in batch]
    if len({len(x) for x in sharp}) == 1:
        out["sharp_surface"] = np.stack(sharp).astype(np.float32)
    else:
        out["sharp_surface"] = [x.astype(np.float32) for x in sharp]
    for name in ("near_points", "near_sdf", "volume_points", "volume_sdf", "volume_occupancy"):
        out[name] = np.stack([get(it, name) for it in batch]).astype(np.float32)
    for name in OPTIONAL_SAMPLE_TENSORS:
        if all(name in (it["samples"] if "samples" in it else it) for it in batch):
            parts = [get(it, name).astype(np.float32) for it in batch]
            same = len({len(x) for x in parts}) == 1
            out[name] = np.stack(parts) if same else parts
    out["ids"] = [it.get("id") for it in batch]
    if to_torch:
        import torch

        for k, v in out.items():
            if isinstance(v, np.ndarray):
                out[k] = torch.from_numpy(v)
    return out


def check_schema_version(path: PathLike) -> None:
    """Raises a ValueError naming the file when a shard (or tensor file) is of another schema
    version than this reader decodes."""
    path = location.of(path)
    _check_version(path, location.parquet_file(path))


def _check_version(path: location.Location, f: pq.ParquetFile) -> None:
    meta = f.metadata.metadata or {}
    version = meta.get(b"sparc3d.schema_version", b"missing").decode()
    if version != str(SCHEMA_VERSION):
        raise ValueError(f"{path}: shard schema version {version}, this reader decodes "
                         f"version {SCHEMA_VERSION} (docs/FORMAT.md)")


def shard_config(path: PathLike) -> Dict[str, Any]:
    """The job config a shard was written with (its `sparc3d.config` metadata); {} if absent."""
    meta = location.parquet_file(location.of(path)).metadata.metadata or {}
    raw = meta.get(b"sparc3d.config")
    return json.loads(raw) if raw else {}


def _item_columns(path: location.Location, f: pq.ParquetFile, samples: bool) -> List[str]:
    """The columns an item is read from; a ValueError names any the file lacks. The sample
    columns are read when asked for and present (jobs without `[samples]` hold them empty)."""
    _check_version(path, f)
    names = f.schema_arrow.names
    jobs.require_columns(path, names, _READ_COLUMNS)
    base = _READ_COLUMNS + [c for c in names if c.startswith(PROVENANCE_PREFIX)]
    if all(c in names for c in _ATTRIBUTE_COLUMNS):
        base = base + _ATTRIBUTE_COLUMNS
    if not (samples and all(c in names for c in _SAMPLE_COLUMNS)):
        return base
    return base + _SAMPLE_COLUMNS + [c for c in _OPTIONAL_SAMPLE_COLUMNS if c in names]


def _rows(path: location.Location, batch_size: int, samples: bool = True) -> Iterator[Dict[str, Any]]:
    f = location.parquet_file(path)
    columns = _item_columns(path, f, samples)
    n = 0
    for batch in f.iter_batches(batch_size=batch_size, columns=columns):
        n += batch.num_rows
        yield from batch.to_pylist()
    _check_row_count(path, n, f.metadata.num_rows)


def _check_row_count(path: location.Location, read: int, stored: int) -> None:
    # pyarrow reads a column chunk whose page header is damaged as no rows at all, silently.
    if read != stored:
        raise ValueError(f"{path}: {read} rows read, its footer says {stored}: the file is "
                         "damaged (read it with verify=True to leave such a shard out)")


@contextlib.contextmanager
def _naming(path: location.Location) -> Iterator[None]:
    """Errors of pyarrow or zstd reading a file (a damaged page, a blob failing zstd's checksum,
    text that is not UTF-8) as a ValueError naming the file."""
    try:
        yield
    except (OSError, pa.ArrowException, UnicodeDecodeError, OverflowError) as e:
        raise ValueError(f"{path}: cannot be read ({type(e).__name__}: {e})") from e


def _shard_item(path: location.Location, row: Dict[str, Any]) -> Dict[str, Any]:
    """`row_to_item`, its errors naming the shard file."""
    try:
        return row_to_item(row)
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from None


def iter_items(paths: Union[PathLike, Iterable[PathLike]], complete_only: bool = True,
               batch_size: int = 16, samples: bool = True,
               verify: Verify = True) -> Iterator[Dict[str, Any]]:
    """Yields every `ok` item of the given jobs / shard files, in shard and item order
    (failed and skipped rows are left out). Reads `batch_size` rows at a time; with
    `samples=False` the sample columns are not read.

    Each shard is checked before its first item is yielded, as `shard_paths` says (`verify`:
    True, "quick" or False); one that fails is left out with a `ShardWarning`."""
    for shard in _shards(paths, complete_only):
        if not _usable(shard, verify):
            continue
        with _naming(shard.path):
            for row in _rows(shard.path, batch_size, samples):
                if row["status"] == "ok":
                    yield _shard_item(shard.path, row)


#: The 8 corners of a cell as offsets from its minimum corner; corner `o` is
#: `(o >> 2 & 1, o >> 1 & 1, o & 1)`, the order of `corner_index` and of `collate_sparse`'s
#: `corners`.
CORNER_OFFSETS = np.array([[(o >> 2) & 1, (o >> 1) & 1, o & 1] for o in range(8)], dtype=np.int64)


def _vertex_keys(xyz: np.ndarray) -> np.ndarray:
    """One int64 per grid point (x, y, z in 0..=4096), ordered as (x, y, z) lexicographically."""
    xyz = xyz.astype(np.int64)
    return (xyz[..., 0] << 26) | (xyz[..., 1] << 13) | xyz[..., 2]


def corner_index(coords: np.ndarray, cells: np.ndarray, item_id: Optional[str] = None) -> np.ndarray:
    """Rows of `coords` ([K, 3], sorted as the shards store them) holding the 8 corners of each
    cell of `cells` ([C, 3] minimum corners): int64 [C, 8] in `CORNER_OFFSETS` order. A ValueError
    names the item when a corner is missing (the shard contract says there is none)."""
    keys = _vertex_keys(np.asarray(coords))
    if len(keys) > 1 and not np.all(keys[1:] > keys[:-1]):
        raise ValueError(f"item {item_id!r}: coords are not sorted and unique (docs/FORMAT.md)")
    want = _vertex_keys(np.asarray(cells)[:, None, :] + CORNER_OFFSETS[None, :, :])
    idx = np.searchsorted(keys, want)
    found = idx < len(keys)
    found[found] = keys[idx[found]] == want[found]
    if not found.all():
        c = int(np.argwhere(~found.all(axis=1))[0, 0])
        raise ValueError(f"item {item_id!r}: cell {np.asarray(cells)[c].tolist()} has a corner "
                         "that is not among the active vertices (docs/FORMAT.md)")
    return idx.astype(np.int64)


def encode_tensor(array: np.ndarray, level: int = 3) -> Tuple[bytes, str, List[int]]:
    """Encodes an array as the shards store tensors (docs/FORMAT.md, "Tensor encoding"): one
    zstd frame, with its content checksum, of its little-endian bytes in byte planes, its numpy
    dtype string and its shape. `decode_tensor` reads it back.

    Needs the `zstandard` package (`pip install sparc3d-reader[write]`): pyarrow's codec
    cannot set the checksum that schema 3 requires and `sparc3d` checks. Reading needs only
    pyarrow."""
    try:
        import zstandard
    except ImportError as e:
        raise ImportError("writing tensor files needs the zstandard package "
                          "(pip install 'sparc3d-reader[write]')") from e
    a = np.ascontiguousarray(array)
    a = a.astype(a.dtype.newbyteorder("<"), copy=False)
    shape = [int(d) for d in a.shape]
    n, k = (shape[0] if shape else 1), int(np.prod(shape[1:]))
    planes = a.reshape(n, k).view(np.uint8).reshape(n, k, a.dtype.itemsize).transpose(1, 2, 0)
    raw = np.ascontiguousarray(planes).tobytes()
    blob = zstandard.ZstdCompressor(level=level, write_checksum=True,
                                    write_content_size=True).compress(raw)
    return blob, a.dtype.str, shape


def write_tensor_file(path: PathLike, rows: Sequence[Dict[str, Any]], tensors: Sequence[str],
                      metadata: Optional[Dict[str, str]] = None,
                      schema: Optional[Dict[str, pa.DataType]] = None) -> None:
    """Writes rows to one Parquet file in the shards' layout: each name in `tensors` becomes
    the three columns `<name>`, `<name>_dtype`, `<name>_shape` (a numpy array per row, or
    None), every other key of the rows a plain column (types from `schema`, else inferred).
    The file carries `sparc3d.schema_version`, so the reader and `sparc3d extract` accept it.
    Written to a temporary name and renamed, so a reader never sees half a file."""
    schema = schema or {}
    plain = [k for k in (rows[0].keys() if rows else []) if k not in tensors]
    columns: Dict[str, pa.Array] = {}
    for k in plain:
        columns[k] = pa.array([r[k] for r in rows], type=schema.get(k))
    for name in tensors:
        enc = [None if r.get(name) is None else encode_tensor(r[name]) for r in rows]
        columns[name] = pa.array([e and e[0] for e in enc], type=pa.binary())
        columns[name + "_dtype"] = pa.array([e and e[1] for e in enc], type=pa.string())
        columns[name + "_shape"] = pa.array([e and e[2] for e in enc], type=pa.list_(pa.int64()))
    table = pa.table(columns)
    meta = {"sparc3d.schema_version": str(SCHEMA_VERSION), **(metadata or {})}
    table = table.replace_schema_metadata({k.encode(): v.encode() for k, v in meta.items()})
    path = pathlib.Path(path)
    tmp = path.with_name(path.name + ".tmp")
    pq.write_table(table, tmp, compression="zstd", use_dictionary=False,
                   write_statistics=False, row_group_size=64)
    os.replace(tmp, path)


def write_completion_record(path: PathLike, fields: Optional[Dict[str, Any]] = None) -> pathlib.Path:
    """Writes the completion record beside a finished tensor file `path` (`part-NNNNN.parquet`
    → `part-NNNNN.complete.json`): its `bytes` and `sha256`, which the reader checks before it
    reads the file (`shard_paths`), plus `fields`. Written to a temporary name and renamed."""
    path = pathlib.Path(path)
    record = {**(fields or {}), "bytes": path.stat().st_size, "sha256": jobs.file_sha256(path)}
    out = _record_beside(path)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(json.dumps(record, sort_keys=True) + "\n")
    os.replace(tmp, out)
    return out


def iter_tensor_rows(paths: Union[PathLike, Iterable[PathLike]], tensors: Sequence[str],
                     complete_only: bool = True, batch_size: int = 16,
                     verify: Verify = True) -> Iterator[Dict[str, Any]]:
    """Yields every row of tensor files (or shards) as a dict: the plain columns as they are,
    each name in `tensors` decoded (None when null; a ValueError names a tensor the file does
    not have). Folders are read like job folders (`shard_paths`, with `verify`)."""
    for path in shard_paths(paths, complete_only, verify):
        f = location.parquet_file(path)
        _check_version(path, f)
        jobs.require_columns(path, f.schema_arrow.names,
                             [f"{t}{s}" for t in tensors for s in ("", "_dtype", "_shape")])
        names = [n for n in f.schema_arrow.names if not any(
            n in (t + "_dtype", t + "_shape") for t in tensors)]
        n = 0
        with _naming(path):
            for batch in f.iter_batches(batch_size=batch_size):
                n += batch.num_rows
                for row in batch.to_pylist():
                    out = {k: row[k] for k in names if k not in tensors}
                    for t in tensors:
                        out[t] = decode_tensor(row, t)
                    yield out
        _check_row_count(path, n, f.metadata.num_rows)


def collate_sparse(batch: Sequence[Dict[str, Any]], to_torch: bool = False) -> Dict[str, Any]:
    """Concatenates items into the layout sparse-convolution libraries expect:

    - `coords` int32 [ΣK, 4]: batch index, x, y, z
    - `feats` float32 [ΣK, 4]: sdf, deformation x, y, z
    - `offsets` int64 [B + 1]: item b's rows are `offsets[b]:offsets[b + 1]`
    - `cells` int32 [ΣC, 4] (batch index + minimum corner) and `cell_offsets` int64 [B + 1]
    - `corners` int64 [ΣC, 8]: the rows of `coords` / `feats` holding each cell's 8 corners,
      in `CORNER_OFFSETS` order (so `feats[corners, 0]` is φ at the corners, [ΣC, 8])
    - `ids`, `resolution` (lists)

    With `to_torch=True` the arrays are torch tensors."""
    ks = [len(it["coords"]) for it in batch]
    cs = [len(it["cells"]) for it in batch]
    coords = np.zeros((sum(ks), 4), dtype=np.int32)
    feats = np.zeros((sum(ks), 4), dtype=np.float32)
    cells = np.zeros((sum(cs), 4), dtype=np.int32)
    offsets = np.zeros(len(batch) + 1, dtype=np.int64)
    cell_offsets = np.zeros(len(batch) + 1, dtype=np.int64)
    offsets[1:] = np.cumsum(ks)
    cell_offsets[1:] = np.cumsum(cs)
    corners = np.zeros((sum(cs), 8), dtype=np.int64)
    for b, it in enumerate(batch):
        lo, hi = offsets[b], offsets[b + 1]
        coords[lo:hi, 0] = b
        coords[lo:hi, 1:] = it["coords"]
        feats[lo:hi, 0] = it["sdf"]
        feats[lo:hi, 1:] = it["deformation"]
        clo, chi = cell_offsets[b], cell_offsets[b + 1]
        cells[clo:chi, 0] = b
        cells[clo:chi, 1:] = it["cells"]
        corners[clo:chi] = corner_index(it["coords"], it["cells"], it.get("id")) + lo
    out: Dict[str, Any] = {
        "coords": coords,
        "feats": feats,
        "offsets": offsets,
        "cells": cells,
        "cell_offsets": cell_offsets,
        "corners": corners,
        "ids": [it["id"] for it in batch],
        "resolution": [it["resolution"] for it in batch],
    }
    if to_torch:
        import torch

        for k in ("coords", "feats", "offsets", "cells", "cell_offsets", "corners"):
            out[k] = torch.from_numpy(out[k])
    return out


class _SparseCubesDatasetBase:
    """Indexable items of jobs / shard files (see `iter_items` for what an item holds).

    Checks the shards as `shard_paths` does (`verify`: True, "quick" or False; a shard that
    fails is left out with a `ShardWarning`) and indexes the `ok` rows once (metadata columns
    only); `ds[i]` reads the row group holding item i (the last one read is cached, so reading
    in order is cheap), after checking that its shard file was not changed since. `transform`,
    when given, is applied to each item."""

    def __init__(self, paths: Union[PathLike, Iterable[PathLike]], complete_only: bool = True,
                 transform=None, verify: Verify = True):
        shards = [s for s in _shards(paths, complete_only) if _usable(s, verify)]
        self.paths = [s.path for s in shards]
        # Each shard with its record and stamp when checked, to notice a later change; without
        # its job (what DataLoader workers are sent stays small).
        self._shards = [dataclasses.replace(s, job=None) for s in shards]
        self.transform = transform
        # (shard number, row group, row within the group) of every ok row.
        self.index: List[Tuple[int, int, int]] = []
        self.ids: List[str] = []
        for s, path in enumerate(self.paths):
            with _naming(path):
                self._index_shard(s, path)
        self._cache: Tuple[Optional[Tuple[int, int]], Optional[pa.Table]] = (None, None)

    def _index_shard(self, s: int, path: location.Location) -> None:
        """Appends the ok rows of shard file `s` to the index."""
        f = location.parquet_file(path)
        jobs.require_columns(path, f.schema_arrow.names, ["id", "status"])
        for g in range(f.metadata.num_row_groups):
            t = f.read_row_group(g, columns=["id", "status"]).to_pydict()
            _check_row_count(path, len(t["id"]), f.metadata.row_group(g).num_rows)
            for r, (id_, status) in enumerate(zip(t["id"], t["status"])):
                if status == "ok":
                    self.index.append((s, g, r))
                    self.ids.append(id_)

    def _row_group(self, s: int, g: int) -> pa.Table:
        """Row group `g` of shard file `s` (cached), once its file is known to be unchanged."""
        key, table = self._cache
        if key != (s, g) or table is None:
            path = self.paths[s]
            jobs.check_unchanged(self._shards[s])
            f = location.parquet_file(path)
            table = f.read_row_group(g, columns=_item_columns(path, f, samples=True))
            _check_row_count(path, table.num_rows, f.metadata.row_group(g).num_rows)
            self._cache = ((s, g), table)
        return table

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, i: int) -> Dict[str, Any]:
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(f"item {i} out of range ({len(self)} items)")
        s, g, r = self.index[i]
        with _naming(self.paths[s]):
            row = self._row_group(s, g).slice(r, 1).to_pylist()[0]
        item = _shard_item(self.paths[s], row)
        return self.transform(item) if self.transform else item

    def __iter__(self) -> Iterator[Dict[str, Any]]:
        for i in range(len(self)):
            yield self[i]

    def __getstate__(self):
        # Worker processes of a DataLoader get a copy without the cached row group. Shards in a
        # bucket are `ObjectPath`s (their URL only): a worker makes its filesystem again.
        state = self.__dict__.copy()
        state["_cache"] = (None, None)
        return state


_dataset_class = None


def _make_dataset_class():
    global _dataset_class
    if _dataset_class is None:
        try:
            import torch.utils.data as tud

            bases = (_SparseCubesDatasetBase, tud.Dataset)
        except ImportError:
            bases = (_SparseCubesDatasetBase,)
        _dataset_class = type("SparseCubesDataset", bases, {
            "__doc__": _SparseCubesDatasetBase.__doc__,
            "__module__": __name__,
        })
    return _dataset_class


def __getattr__(name: str):
    # `SparseCubesDataset` is built on first use, so importing this package never imports torch.
    if name == "SparseCubesDataset":
        return _make_dataset_class()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def read_job_config(job: PathLike) -> Dict[str, Any]:
    """The config of a job folder or job URL (`job.json`'s `config`)."""
    root = location.of(job)
    if isinstance(root, ObjectPath):
        location.require_job(root)
    return json.loads(location.read_text(root / "job.json"))["config"]


# --- Layouts of other codebases, written by `sparc3d export` -------------------------------

#: The formats of `sparc3d export`.
#: Exports this module reads back (`iter_export`, `ExportDataset`, the `collate_*` functions):
#: one `<index>-<stem>.npz` per item in our layouts.
EXPORT_FORMATS = ("vecset-npz", "direct3d-s2", "cubvh")
#: Exports in another codebase's own layout, read by that codebase's loader (docs/FORMAT.md,
#: "Exports"); `run_export` writes them too.
CONSUMER_FORMATS = ("hunyuan3d-2.1", "dora", "step1x-3d", "triposg", "trellis2")


def run_export(job: PathLike, fmt: str, out: PathLike, ids: Optional[Sequence[str]] = None,
               frame: Optional[str] = None, binary: str = "sparc3d") -> pathlib.Path:
    """Runs `sparc3d export JOB --format FMT --out OUT` (the geometry of every layout lives in
    the Rust CLI, so Python never recomputes it) and returns the output folder. `frame`: None
    for the format's own (the consumer's cube; `normalized` for vecset-npz), else `consumer`,
    `normalized` or `source`."""
    import subprocess

    if fmt not in EXPORT_FORMATS + CONSUMER_FORMATS:
        raise ValueError(f"unknown format {fmt!r}; one of "
                         f"{', '.join(EXPORT_FORMATS + CONSUMER_FORMATS)}")
    cmd = [binary, "export", str(job), "--format", fmt, "--out", str(out)]
    if frame is not None:
        cmd += ["--frame", frame]
    if ids:
        cmd += ["--ids", ",".join(ids)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr.strip()}")
    return pathlib.Path(out)


def _load_npz(path: pathlib.Path) -> Dict[str, Any]:
    with np.load(path) as z:
        item = {k: z[k] for k in z.files}
    # Every export names its item inside (`id`, `item_index`); files of older versions did
    # not, and were named after the id.
    item["id"] = str(item["id"]) if "id" in item else path.stem
    if "item_index" in item:
        item["item_index"] = int(item["item_index"])
    return item


def iter_export(folder: PathLike) -> Iterator[Dict[str, Any]]:
    """Yields the arrays of every `.npz` in an export folder (sorted by name, which is
    manifest order), with `id` (str) and `item_index` (int) from inside the file."""
    for path in sorted(pathlib.Path(folder).glob("*.npz")):
        yield _load_npz(path)


class ExportDataset:
    """The `.npz` files of an export folder as an indexable dataset (`ds[i]` is a dict of
    arrays); works as a `torch.utils.data.Dataset` with `DataLoader` and the collate
    functions below."""

    def __init__(self, folder: PathLike, transform=None):
        self.paths = sorted(pathlib.Path(folder).glob("*.npz"))
        self.transform = transform

    def __len__(self) -> int:
        return len(self.paths)

    def __getitem__(self, i: int) -> Dict[str, Any]:
        item = _load_npz(self.paths[i])
        return self.transform(item) if self.transform else item


def _batch_coords(parts: Sequence[np.ndarray]) -> np.ndarray:
    """int32 [ΣN, 4]: batch index, then the item's (x, y, z)."""
    total = sum(len(p) for p in parts)
    out = np.zeros((total, 4), dtype=np.int32)
    lo = 0
    for b, p in enumerate(parts):
        out[lo:lo + len(p), 0] = b
        out[lo:lo + len(p), 1:] = p
        lo += len(p)
    return out


def _torch(out: Dict[str, Any], to_torch: bool) -> Dict[str, Any]:
    if to_torch:
        import torch

        for k, v in out.items():
            if isinstance(v, np.ndarray):
                out[k] = torch.from_numpy(v)
    return out


def collate_direct3d_s2(batch: Sequence[Dict[str, Any]], to_torch: bool = False) -> Dict[str, Any]:
    """Direct3D-S2 items → the batch its sparse SDF VAE encodes (`ss_vae.py` reads
    `sparse_sdf`, `sparse_index`, `batch_idx`): `sparse_sdf` float32 [ΣN, 1] in (−1, 1),
    `sparse_index` int32 [ΣN, 3], `batch_idx` int64 [ΣN], and `coords` int32 [ΣN, 4]."""
    coords = _batch_coords([np.asarray(it["sparse_index"]) for it in batch])
    out = {
        "coords": coords,
        "sparse_index": coords[:, 1:].copy(),
        "batch_idx": coords[:, 0].astype(np.int64),
        "sparse_sdf": np.concatenate([np.asarray(it["sparse_sdf"], np.float32).reshape(-1, 1)
                                      for it in batch]),
        "ids": [it.get("id") for it in batch],
    }
    return _torch(out, to_torch)


def cubvh_cells(item: Dict[str, Any]) -> np.ndarray:
    """The cells of a cubvh item, int32 [N, 3], from its packed `active_cells`."""
    res = int(item["resolution"])
    c = np.asarray(item["active_cells"], dtype=np.uint64)
    return np.stack([c // (res * res), c // res % res, c % res], axis=1).astype(np.int32)


def cubvh_corner_values(item: Dict[str, Any]) -> np.ndarray:
    """The 8 corner values of each cubvh cell, float32 [N, 8] in voxels (cubvh's corner order
    000, 100, 110, 010, 001, 101, 111, 011; negative inside), from the packed bytes."""
    packed = np.asarray(item["active_cells_sdf"], dtype=np.uint64)
    codes = (packed[:, None] >> (np.arange(8, dtype=np.uint64) * np.uint64(8))) & np.uint64(0xFF)
    codes = codes.astype(np.uint8)
    mag = (codes & 0x7F).astype(np.float32) * np.float32(np.sqrt(3.0) / 127.0)
    return np.where(codes & 0x80, -mag, mag).astype(np.float32)


def collate_cubvh(batch: Sequence[Dict[str, Any]], to_torch: bool = False) -> Dict[str, Any]:
    """cubvh items → `coords` int32 [ΣN, 4] (batch index first) and `corners` float32 [ΣN, 8]
    (corner values in voxels, cubvh's corner order), `codes` uint8 [ΣN, 8] (the stored sign +
    magnitude bytes)."""
    coords = _batch_coords([cubvh_cells(it) for it in batch])
    packed = np.concatenate([np.asarray(it["active_cells_sdf"], np.uint64) for it in batch])
    codes = ((packed[:, None] >> (np.arange(8, dtype=np.uint64) * np.uint64(8))) & np.uint64(0xFF)).astype(np.uint8)
    out = {
        "coords": coords,
        "corners": np.concatenate([cubvh_corner_values(it) for it in batch]),
        "codes": codes,
        "ids": [it.get("id") for it in batch],
    }
    return _torch(out, to_torch)
