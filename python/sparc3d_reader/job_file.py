"""A job as the reader knows it: `job.json` and, on first use, the ids and uris of its frozen
manifest (`manifest.jsonl`, or the slice of each shard under `manifest/` that `job.json`'s index
pages pin), and the job a folder or a shard file belongs to. The checks of its shards import
`Job` from here; `jobs` is where their names meet (its docs say what a shard must pass).
"""

from __future__ import annotations

import bisect
import dataclasses
import hashlib
import json
import os
import pathlib
import re
from typing import Dict, List, Optional, Tuple, Union

from . import location
from .location import Location, ObjectPath

_SHARD_NAME = re.compile(r"^part-(\d{5,})\.parquet$")

# Shards one index page of a sliced frozen manifest lists (schema/src/job/manifest.rs PAGE_SHARDS).
PAGE_SHARDS = 1024


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
