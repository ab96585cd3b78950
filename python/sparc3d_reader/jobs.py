"""Which shards of a job are read, checked the way the `sparc3d` CLI checks them
(docs/RELIABILITY.md, "Finished shards" and "The Python reader"). A job is a folder or a URL of
a bucket prefix (`location.py`); both are read by the same code.

A job's shards are `shards/part-NNNNN.parquet` for N below `job.json`'s `shards`, or the object
`shards/<object>` that the record names (writers to a bucket upload under names of their own).
One is read only when its completion record `part-NNNNN.complete.json` parses, has the job's
fingerprint (another is an error, as in the CLI: a mixed job), is this shard's, and the file
matches it: its size and sha256 (`verify=True`, what `inspect`/`show` do), or its size and stamp
with the sha256 only when the stamp changed (`verify="quick"`, what `run`/`status` do; an object
has no stamp: it is hashed only when modified after its record was created), or its size only
(`verify=False`). Its footer must name the job's fingerprint, and its rows are checked against
the frozen manifest before any is returned: one row per item of the shard, in order, with the
manifest's id and uri, a known status, as many ok rows as the record counts, the job's
resolution and a normalization the converter can produce.

A shard that is not read for any of these reasons, and any other `.parquet` file in `shards/`
(a stray `part-00099`), is named in a `ShardWarning`, with its quarantine folder when `run` or
`verify` moved it aside. In a bucket, `part-NNNNN.<token>.parquet` objects that no record names
are uploads of writers that lost a race or died before their record: not shards, not named. `warnings.simplefilter("error", ShardWarning)` makes them errors.
"""

from __future__ import annotations

import bisect
import dataclasses
import hashlib
import json
import math
import os
import pathlib
import re
import sys
import warnings
from typing import Dict, List, Optional, Sequence, Tuple, Union

import pyarrow.parquet as pq

from . import location
from .location import Location, ObjectPath
from .schema import META_COLUMNS, META_FINGERPRINT, STATUSES

Verify = Union[bool, str]

#: The values of `verify`: True (or "full") hashes every shard, "quick" only those whose
#: stamp changed, False none.
VERIFY_MODES = (True, "full", "quick", False)


def check_verify_mode(verify: Verify) -> None:
    """A ValueError unless `verify` is one of VERIFY_MODES (1 and 0 are not)."""
    if not any(verify is m if isinstance(m, bool) else verify == m for m in VERIFY_MODES):
        raise ValueError(f"verify={verify!r}: one of True, 'full', 'quick', False")

_SHARD_NAME = re.compile(r"^part-(\d{5,})\.parquet$")
#: A writer's upload of a shard's data to a bucket, `part-NNNNN.<token>.parquet`: the shard's
#: data when its record names it (`object`), else a leftover of a writer that lost the race for
#: the record or died before writing it.
_UPLOAD_NAME = re.compile(r"^part-(\d{5,})\.[^/\\]+\.parquet$")

# Normalizations the converter can produce (sparcubes/src/normalize.rs): the longest side of a
# mesh lies in [1e-15, 1e15] and the grid uses at most all of the unit cube, so the scale is at
# most 1e15; coordinates are float32, so a centre lies within float32's range.
_MAX_SCALE = 1e15
_MAX_CENTER = 3.5e38


# Shards one index page of a sliced frozen manifest lists (schema/src/manifest.rs PAGE_SHARDS).
PAGE_SHARDS = 1024


class ShardWarning(UserWarning):
    """A shard of a job that is not read (not finished, damaged, quarantined) or a file in
    `shards/` that is not one of the job's shards; the message names it and says why."""


@dataclasses.dataclass
class Job:
    """What the checks need of a job (a folder or a bucket prefix): `job.json` and, on first
    use, the ids and uris of its frozen manifest."""

    root: Location
    fingerprint: str
    items: int
    shards: int
    shard_size: int
    resolution: Optional[int]
    # The index pages `job.json` pins (a job kept in slices, one a shard, under `manifest/`);
    # None for a job made before slices, whose frozen manifest is `manifest.jsonl`.
    pages: Optional[List[dict]] = None
    _items: Optional[List[Tuple[str, str]]] = None
    _shards: Optional[List[int]] = None
    _page_entries: Optional[Dict[int, List[Tuple[int, int, str]]]] = None

    def shard_file(self, shard: int) -> Location:
        """`shards/part-NNNNN.parquet`."""
        return self.root / "shards" / f"part-{shard:05d}.parquet"

    def record_file(self, shard: int) -> Location:
        """`shards/part-NNNNN.complete.json`, the completion record."""
        return self.root / "shards" / f"part-{shard:05d}.complete.json"

    def data_file(self, shard: int, record: dict) -> Tuple[Location, Optional[str]]:
        """The file holding a finished shard's rows: `shards/<object>` when its record names
        one, else `shards/part-NNNNN.parquet`; and why the record's `object` cannot be this
        shard's (None when it can): it must be `part-NNNNN.parquet` or
        `part-NNNNN.<token>.parquet` of this shard, a name within `shards/`."""
        name = record.get("object")
        if name is None:
            return self.shard_file(shard), None
        own = re.compile(rf"part-{shard:05d}(\.[^/\\]+)?\.parquet")
        if not isinstance(name, str) or not own.fullmatch(name):
            return self.shard_file(shard), (
                f"its completion record names object {name!r}, not one of shard {shard}'s "
                f"(part-{shard:05d}.parquet or part-{shard:05d}.<token>.parquet)")
        return self.root / "shards" / name, None

    def shard_items(self, shard: int) -> range:
        """Manifest positions of the items of a shard: those frozen with that shard
        (`index // shard_size` for a job made at once; each `sparc3d add` starts new shards).
        A sliced job reads the shard's index page only."""
        if self.pages is not None:
            first, count, _ = self._entry(shard)
            return range(first, first + count)
        if self._shards is None:
            self._read_manifest()
        shards = self._shards or []
        start = bisect.bisect_left(shards, shard)
        return range(start, bisect.bisect_right(shards, shard))

    def manifest(self) -> List[Tuple[str, str]]:
        """(id, uri) of every item of the frozen manifest, in order (every slice read)."""
        if self.pages is not None:
            return [pair for shard in range(self.shards) for pair in self.shard_manifest(shard)]
        if self._items is None:
            self._read_manifest()
        return self._items or []

    def shard_manifest(self, shard: int) -> List[Tuple[str, str]]:
        """(id, uri) of the items of one shard, in order: its slice alone for a sliced job."""
        if self.pages is None:
            manifest = self.manifest()
            return [manifest[i] for i in self.shard_items(shard)]
        first, count, sha = self._entry(shard)
        path = self.root / "manifest" / f"part-{shard:05d}.{sha[:16]}.jsonl"
        items = _manifest_items(path, sha)
        if len(items) != count or any(s != shard for _, _, s in items):
            raise ValueError(f"{path}: not the {count} items of shard {shard} its index page lists")
        return [(i, u) for i, u, _ in items]

    def _entry(self, shard: int) -> Tuple[int, int, str]:
        """(first item, items, slice sha256) of `shard` from its index page (read once)."""
        page = shard // PAGE_SHARDS
        if not 0 <= shard < self.shards or self.pages is None:
            raise ValueError(f"{self.root}: the job has no shard {shard}")
        if self._page_entries is None:
            self._page_entries = {}
        if page not in self._page_entries:
            pin = self.pages[page]
            path = self.root / "manifest" / f"index-{page:05d}.{pin['sha256'][:16]}.tsv"
            data = location.read_bytes(path)
            if hashlib.sha256(data).hexdigest() != pin["sha256"]:
                raise ValueError(f"{path}: its sha256 is not the one job.json pins (edited after init?)")
            entries = []
            for line in data.decode().splitlines():
                _, first, count, sha = line.split("\t")
                entries.append((int(first), int(count), sha))
            self._page_entries[page] = entries
        return self._page_entries[page][shard % PAGE_SHARDS]

    def _read_manifest(self) -> None:
        items = _manifest_items(self.root / "manifest.jsonl")
        self._items = [(i, u) for i, u, _ in items]
        self._shards = [s for _, _, s in items]


def open_job(root: Union[str, os.PathLike, ObjectPath]) -> Job:
    """The job in folder `root`, or at a job URL (`s3://bucket/prefix`, `gs://`, `az://`); a
    ValueError naming `job.json` when it is not one. For a URL, a FileNotFoundError or
    ValueError names what is missing (the object, the bucket) or what to set (credentials,
    endpoint) when job.json cannot be read (`location.require_job`)."""
    root = location.of(root)
    if isinstance(root, ObjectPath):
        location.require_job(root)
    path = root / "job.json"
    try:
        job = json.loads(location.read_text(path))
        config = job["config"]
        return Job(root=root, fingerprint=str(job["fingerprint"]), items=int(job["items"]),
                   shards=int(job["shards"]), shard_size=max(int(config["shard_size"]), 1),
                   resolution=config.get("params", {}).get("resolution"),
                   pages=job.get("manifest_pages"))
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise ValueError(f"{path}: not a readable job file ({type(e).__name__}: {e})") from None


def job_of_folder(folder: pathlib.Path) -> Optional[Job]:
    """The job of a job folder or of its `shards/` folder; None for any other folder."""
    for root in (folder, folder.parent):
        if (root / "job.json").is_file() and (root / "shards").resolve() in (
                (folder / "shards").resolve(), folder.resolve()):
            return open_job(root)
    return None


def job_of_file(path: pathlib.Path) -> Tuple[Optional[Job], Optional[int]]:
    """The job and shard index of a shard file named as one of its job's shards
    (`JOB/shards/part-NNNNN.parquet`); (None, None) for any other file."""
    m = _SHARD_NAME.match(path.name)
    if m is None or path.parent.name != "shards" or not (path.parent.parent / "job.json").is_file():
        return None, None
    job = open_job(path.parent.parent)
    shard = int(m.group(1))
    return (job, shard) if shard < job.shards and path.name == job.shard_file(shard).name else (None, None)


def _manifest_items(path: Location, sha256: Optional[str] = None) -> List[Tuple[str, str, int]]:
    """(id, uri, shard) of each line of a frozen manifest file; with `sha256`, the file's bytes
    are checked against it first."""
    items = []
    try:
        if sha256 is not None:
            data = location.read_bytes(path)
            if hashlib.sha256(data).hexdigest() != sha256:
                raise ValueError("its sha256 is not the one its index page lists (edited after init?)")
            lines = data.decode().splitlines()
        else:
            with location.open_text(path) as f:
                lines = list(f)
        for line in lines:
            if line.strip():
                record = json.loads(line)
                items.append((record["id"], record["uri"], int(record["shard"])))
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise ValueError(f"{path}: the frozen manifest cannot be read ({type(e).__name__}: {e})") from None
    return items


# --- one shard against its completion record ------------------------------------------------


@dataclasses.dataclass
class Shard:
    """A shard file to read: its job and index (None for a file outside a job), its completion
    record (None when it has none) and the file's stamp once checked, to notice a later change."""

    path: Location
    job: Optional[Job] = None
    index: Optional[int] = None
    record: Optional[dict] = None
    stamp: Optional[Tuple[int, int, int, int]] = None
    #: Why its completion record cannot be used (it does not parse), if so.
    torn: Optional[str] = None
    #: The file opened to check its footer and rows, until the reader that reads the rows
    #: takes it (`shards.take_file`): a shard is opened once on the way to its first row.
    #: Never copied (`dataclasses.replace`), compared or shown.
    file: Optional[pq.ParquetFile] = dataclasses.field(default=None, init=False, repr=False,
                                                       compare=False)


_stamp = location.stamp


def file_sha256(path: Location) -> str:
    """Hex sha256 of a file's (or an object's) bytes, read in 4 MiB blocks."""
    return location.sha256(path)


# Files that matched their record in this process, by path: (size, mtime, ctime, inode, sha256).
# A file whose stamp is unchanged since has not been written (the ctime cannot be set back), so
# opening the same job again, or its shard files one by one, hashes nothing twice. Objects are
# not remembered: their stamp (size and a time to the second) does not show every rewrite.
_verified: Dict[str, Tuple[int, int, int, int, str]] = {}


def read_record(path: Location) -> Tuple[Optional[dict], Optional[str]]:
    """The completion record at `path`: (None, None) when absent, (None, why) when it does
    not parse, else (record, None)."""
    try:
        text = location.read_bytes(path)
    except FileNotFoundError:
        return None, None
    try:
        record = json.loads(text)
        if not isinstance(record, dict):
            raise ValueError("not a JSON object")
        return record, None
    except ValueError as e:
        return None, f"its completion record {path} does not parse ({e})"


def check_against_record(shard: Shard, verify: Verify) -> Optional[str]:
    """None when the shard file matches its completion record as far as `verify` looks (and
    `shard.stamp` is set), else why not. A record with another config's fingerprint is a
    ValueError, as in the CLI."""
    job, record = shard.job, shard.record or {}
    if job is not None and record.get("fingerprint") != job.fingerprint:
        raise ValueError(
            f"{shard.path}: its completion record has fingerprint {record.get('fingerprint')}, "
            f"the job {job.root} has {job.fingerprint}: a shard of another config (configs are "
            "never mixed; use a new job folder)")
    if job is not None and record.get("shard") != shard.index:
        return f"its completion record is shard {record.get('shard')}'s"
    try:
        stamp = _stamp(shard.path)
    except FileNotFoundError:
        return f"{shard.path} is missing"
    if stamp[0] != record.get("bytes"):
        return f"{shard.path} has {stamp[0]} bytes, its completion record says {record.get('bytes')}"
    why = _check_sha(shard, stamp, verify)
    if why is None:
        shard.stamp = stamp
    return why


def _check_sha(shard: Shard, stamp: Tuple[int, int, int, int], verify: Verify) -> Optional[str]:
    record = shard.record or {}
    local = isinstance(shard.path, pathlib.Path)
    if verify is False or (local and _verified.get(str(shard.path)) == (*stamp, record.get("sha256"))):
        return None
    if verify == "quick" and _unchanged_since_record(shard, stamp):
        return None
    sha = file_sha256(shard.path)
    if sha != record.get("sha256"):
        return (f"{shard.path} has sha256 {sha}, its completion record says "
                f"{record.get('sha256')} (the file changed after it was written)")
    if local:
        _verified[str(shard.path)] = (*stamp, sha)
    return None


def _unchanged_since_record(shard: Shard, stamp: Tuple[int, int, int, int]) -> bool:
    """Whether the file is as its record found it, by what its store keeps: on disk the
    record's `stamp` (a record without one: no); in a bucket, where records have no stamp, the
    object not modified after its record was created, both times by the store's clock (a writer
    uploads its object, then creates the record). An object rewritten within the second its
    record was created passes; `verify=True` notices it."""
    if isinstance(shard.path, ObjectPath):
        if shard.job is None or shard.index is None:
            return False
        try:
            created = location.stamp(shard.job.record_file(shard.index))[1]
        except FileNotFoundError:
            return False
        return 0 < stamp[1] <= created
    recorded = (shard.record or {}).get("stamp") or {}
    return (recorded.get("modified_ns"), recorded.get("changed_ns"), recorded.get("inode")) == stamp[1:]


def check_unchanged(shard: Shard) -> None:
    """A ValueError when the shard file changed since it was checked (a `run` or `verify`
    replaced or moved it while a dataset was open). A file whose stamp changed but whose bytes
    still match its record (copied back, touched) is fine, as in the CLI's quick check."""
    if shard.stamp is None:
        return
    try:
        now: Optional[Tuple[int, int, int, int]] = _stamp(shard.path)
    except FileNotFoundError:
        now = None
    if now == shard.stamp:
        return
    why = "it is gone" if now is None or shard.record is None else check_against_record(shard, True)
    if why is not None:
        raise ValueError(f"{shard.path} changed since it was checked ({why}): its rows may "
                         "have moved; open the dataset again")


# --- the shards of a job folder -------------------------------------------------------------


def job_shards(job: Job, complete_only: bool) -> List[Shard]:
    """The job's own shards that have a completion record that parses (and, unless
    `complete_only`, those without one), in order. Every other shard and every stray file in
    `shards/` is named in a ShardWarning. Records are not checked against files here
    (`check_against_record` does)."""
    out: List[Shard] = []
    notes: List[str] = []
    for i in range(job.shards):
        record, torn = read_record(job.record_file(i))
        path = job.shard_file(i)
        if record is not None:
            data, torn = job.data_file(i, record)
        if torn is not None:
            notes.append(f"{path.name}: damaged, {torn}")
        elif record is not None:
            out.append(Shard(data, job, i, record))
        elif complete_only or not location.exists(path):
            notes.append(f"{path.name}: not finished")
        else:
            out.append(Shard(path, job, i, None))
    _warn_not_read(job, notes, _quarantined(job))
    _warn_strays(job, {s.path.name for s in out})
    return out


def _quarantined(job: Job) -> Dict[str, List[str]]:
    """Shard name → its folders in `quarantine/` with the first line of their reason."""
    found: Dict[str, List[str]] = {}
    for d in location.entries(job.root / "quarantine"):
        name = d.name.rsplit("-", 1)[0]
        try:
            reason = location.read_text(d / "reason.txt", errors="replace").strip().splitlines()[0]
        except (OSError, IndexError):
            reason = "no reason.txt"
        found.setdefault(name, []).append(f"quarantine/{d.name} ({reason})")
    return found


def _warn_not_read(job: Job, notes: List[str], quarantined: Dict[str, List[str]]) -> None:
    if not notes:
        return
    lines = []
    for note in notes:
        name = note.split(".parquet", 1)[0]
        moved = quarantined.get(name)
        lines.append(note + (f"; moved aside to {', '.join(moved)}" if moved else ""))
    warn_shards(f"{job.root}: {len(notes)} of {job.shards} shards are not read, their items "
                f"left out: {'; '.join(lines)}. `sparc3d status {job.root}` shows the job; "
                f"`sparc3d run {job.root}` converts what is left")


def _warn_strays(job: Job, read: set) -> None:
    """Names every `.parquet` in `shards/` that is neither a shard's slot
    (`part-NNNNN.parquet`) nor read (`read`: the objects records name). In a bucket, writers'
    uploads that no record names (`part-NNNNN.<token>.parquet`) are left without a word: a
    writer that lost the race for a record, or died before writing it, leaves one."""
    own = {job.shard_file(i).name for i in range(job.shards)} | read
    bucket = isinstance(job.root, ObjectPath)
    strays = sorted(n for n in location.parquet_names(job.root / "shards")
                    if not n.startswith(".") and n not in own
                    and not (bucket and _UPLOAD_NAME.match(n)))
    if strays:
        last = job.shard_file(max(job.shards - 1, 0)).name
        warn_shards(f"{job.root}: ignored {', '.join(strays)} in shards/: not one of the "
                    f"job's {job.shards} shards (part-00000.parquet … {last})")


def warn_shards(message: str) -> None:
    """Issues a ShardWarning, attributed to the first caller outside this package."""
    package = os.path.dirname(os.path.abspath(__file__))
    frame, level = sys._getframe(1), 2
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(package):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, ShardWarning, stacklevel=level)


# --- the rows of a shard against the frozen manifest ----------------------------------------

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
