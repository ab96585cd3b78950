"""The shards' tensor encoding (docs/FORMAT.md, "Tensor encoding") and tensor files.

A tensor is one zstd frame, with its content checksum, of its elements' little-endian bytes
grouped into byte planes, with its numpy dtype string and its shape in two columns beside it.
Tensor files are Parquet files in the same encoding with other columns (docs/FORMAT.md, "Tensor
files"): decoded cubes for `sparc3d extract`, latents of `sparc3d-vae encode`. Encoding and
decoding live here only, so a format change is made in one place.
"""

from __future__ import annotations

import json
import os
import pathlib
from typing import Any, Dict, Iterable, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from . import records, row_checks
from .records import Verify
from .schema import META_SCHEMA_VERSION, SCHEMA_VERSION, tensor_columns
from .shards import (PathLike, all_shards, check_row_count, check_version, naming,
                     record_beside, take_file, usable)


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
    meta = {META_SCHEMA_VERSION: str(SCHEMA_VERSION), **(metadata or {})}
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
    record = {**(fields or {}), "bytes": path.stat().st_size, "sha256": records.file_sha256(path)}
    out = record_beside(path)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(json.dumps(record, sort_keys=True) + "\n")
    os.replace(tmp, out)
    return out


def iter_tensor_rows(paths: Union[PathLike, Iterable[PathLike]], tensors: Sequence[str],
                     complete_only: bool = True, batch_size: int = 16,
                     verify: Verify = True) -> Iterator[Dict[str, Any]]:
    """Yields every row of tensor files (or shards) as a dict: the plain columns as they are,
    each name in `tensors` decoded (None when null; a ValueError names a tensor the file does
    not have). Folders are read like job folders (`shard_paths`, with `verify`): each file is
    checked, as `iter_items` checks it, before its first row is yielded."""
    for shard in all_shards(paths, complete_only):
        if usable(shard, verify):
            yield from _tensor_rows(shard.path, take_file(shard), tensors, batch_size)


def _tensor_rows(path: PathLike, f: pq.ParquetFile, tensors: Sequence[str],
                 batch_size: int) -> Iterator[Dict[str, Any]]:
    """Every row of the tensor file `f` (opened from `path`), its `tensors` decoded."""
    check_version(path, f)
    row_checks.require_columns(path, f.schema_arrow.names, tensor_columns(tensors))
    names = [n for n in f.schema_arrow.names if not any(
        n in (t + "_dtype", t + "_shape") for t in tensors)]
    n = 0
    with naming(path):
        for batch in f.iter_batches(batch_size=batch_size):
            n += batch.num_rows
            for row in batch.to_pylist():
                out = {k: row[k] for k in names if k not in tensors}
                for t in tensors:
                    out[t] = decode_tensor(row, t)
                yield out
    check_row_count(path, n, f.metadata.num_rows)
