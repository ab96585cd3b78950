"""The rows of a job's shard against its frozen manifest, checked before any is returned: the
footer names the job's fingerprint; one row per item of the shard, in order, with the manifest's
id and uri, a known status, as many ok rows as the record counts, the job's resolution and a
normalization the converter can produce.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Dict, List, Optional, Sequence, Tuple

import pyarrow.parquet as pq

from .location import Location
from .records import Shard
from .schema import META_COLUMNS, META_FINGERPRINT, STATUSES

if TYPE_CHECKING:
    from .job_file import Job

# Normalizations the converter can produce (sparcubes/src/normalize.rs): the longest side of a
# mesh lies in [1e-15, 1e15] and the grid uses at most all of the unit cube, so the scale is at
# most 1e15; coordinates are float32, so a centre lies within float32's range.
_MAX_SCALE = 1e15
_MAX_CENTER = 3.5e38


#: Columns the row checks read (small: no tensors): the metadata columns of every item.
CHECK_COLUMNS = META_COLUMNS


def check_footer(shard: Shard, f: pq.ParquetFile) -> Optional[str]:
    """None when a job shard's footer names the job's fingerprint, else what it names."""
    meta = f.metadata.metadata or {}
    found = meta.get(META_FINGERPRINT.encode(), b"missing").decode(errors="replace")
    if shard.job is not None and found != shard.job.fingerprint:
        return f"its footer has fingerprint {found}, the job's is {shard.job.fingerprint}"
    return None


def check_rows(shard: Shard, columns: Dict[str, Sequence]) -> Optional[str]:
    """None when a job shard's rows (`columns`: CHECK_COLUMNS of every row) are its items: one
    row each, in manifest order, with the manifest's id and uri and a known status, as many ok
    rows as its record counts, and every ok row with the job's resolution and a normalization
    the converter can produce; else what is wrong. Files outside a job are not checked."""
    job = shard.job
    if job is None or shard.index is None:
        return None
    expected = list(job.shard_items(shard.index))
    indices = list(columns["item_index"])
    if indices != expected:
        return (f"its rows are items {_span(indices)}, shard {shard.index} holds items "
                f"{_span(expected)} (a file restored into another shard's slot?)")
    manifest = job.shard_manifest(shard.index)
    for r, index in enumerate(indices):
        row = {k: columns[k][r] for k in CHECK_COLUMNS}
        why = _not_the_item(row, manifest[index - expected[0]]) or (
            _implausible(job, row) if row["status"] == "ok" else None)
        if why:
            return f"row of item {index} ({row['id']!r}): {why}"
    ok = sum(1 for s in columns["status"] if s == "ok")
    if shard.record is not None and ok != shard.record.get("ok"):
        return f"{ok} ok rows, its completion record counts {shard.record.get('ok')}"
    return None


def _not_the_item(row: Dict, item: Tuple[str, str]) -> Optional[str]:
    if row["id"] != item[0]:
        return f"the manifest says id {item[0]!r}"
    if row["uri"] != item[1]:
        return f"uri {row['uri']!r}, the manifest says {item[1]!r}"
    if row["status"] not in STATUSES:
        return f"status {row['status']!r} is none of {', '.join(STATUSES)}"
    return None


def _implausible(job: Job, row: Dict) -> Optional[str]:
    if job.resolution is not None and row["resolution"] != job.resolution:
        return f"resolution {row['resolution']}, the job's is {job.resolution}"
    scale = row["scale"]
    if scale is None or not (0 < scale <= _MAX_SCALE):
        return f"scale {scale} is outside (0, {_MAX_SCALE:g}]"
    for axis in "xyz":
        c = row[f"center_{axis}"]
        if c is None or not math.isfinite(c) or abs(c) > _MAX_CENTER:
            return f"center_{axis} {c} is outside ±{_MAX_CENTER:g}"
    return None


def _span(indices: List[int]) -> str:
    if not indices:
        return "none"
    if indices == list(range(indices[0], indices[0] + len(indices))):
        return f"{indices[0]}–{indices[-1]}"
    return ", ".join(map(str, indices[:8])) + (" …" if len(indices) > 8 else "")


def read_check_columns(path: Location, f: pq.ParquetFile) -> Dict[str, list]:
    """CHECK_COLUMNS of every row of the shard file `f` (opened from `path`)."""
    require_columns(path, f.schema_arrow.names, CHECK_COLUMNS)
    return f.read(columns=CHECK_COLUMNS).to_pydict()


def require_columns(path: Location, present: Sequence[str], wanted: Sequence[str]) -> None:
    """A ValueError naming the file and every column of `wanted` it lacks."""
    missing = [c for c in wanted if c not in set(present)]
    if missing:
        raise ValueError(f"{path}: no column {', '.join(map(repr, missing))} (a shard has every "
                         "column of docs/FORMAT.md, \"Columns\"; a tensor file is read with "
                         "iter_tensor_rows)")
