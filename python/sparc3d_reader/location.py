"""Where a job lives: a local folder, read as it always was (a `pathlib.Path`), or a URL of
an object store (`s3://bucket/prefix`, `gs://bucket/prefix`, `az://container/prefix`), read
through a `pyarrow.fs` filesystem configured from the environment (docs/CLUSTER.md,
"Credentials").

A `Location` is either. The functions here read, list and stat both kinds, so a job's modules
(`jobs.py`, `job_listing.py`, `records.py`) have one code path. An `ObjectPath` holds only its
URL: pickled into a DataLoader worker, it makes its filesystem again there, from that process's
environment.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import io
import os
import pathlib
import re
from typing import Dict, Iterator, List, Optional, TextIO, Tuple, Union

import pyarrow.fs as pafs
import pyarrow.parquet as pq

#: URL schemes of object stores the reader reads a job from.
SCHEMES = ("s3", "gs", "az")

_URL = re.compile(r"^([A-Za-z][A-Za-z0-9+.-]*)://(.*)$", re.S)


@dataclasses.dataclass(frozen=True)
class ObjectPath:
    """An object, or a prefix, in a bucket: `str()` is its URL (`s3://bucket/key`). Offers the
    part of pathlib's API the reader uses: `/`, `name`, `parent`, `with_name`."""

    #: `s3`, `gs` or `az`.
    scheme: str
    #: `bucket/key` as pyarrow's filesystems name it: no leading or trailing slash.
    key: str

    @property
    def bucket(self) -> str:
        """The bucket (or container): the key's first part."""
        return self.key.split("/", 1)[0]

    @property
    def name(self) -> str:
        """The key's last part, as `pathlib.Path.name`."""
        return self.key.rsplit("/", 1)[-1]

    @property
    def parent(self) -> "ObjectPath":
        """The prefix holding this object (the bucket itself has none above it)."""
        return ObjectPath(self.scheme, self.key.rsplit("/", 1)[0]) if "/" in self.key else self

    def __truediv__(self, name: str) -> "ObjectPath":
        return ObjectPath(self.scheme, f"{self.key}/{name}")

    def with_name(self, name: str) -> "ObjectPath":
        """The object beside this one called `name`."""
        return self.parent / name

    def __str__(self) -> str:
        return f"{self.scheme}://{self.key}"


Location = Union[pathlib.Path, ObjectPath]


def of(path: Union[str, os.PathLike, ObjectPath]) -> Location:
    """A local path as a `pathlib.Path`, a job URL (`s3://`, `gs://`, `az://`; `file://` is a
    local path) as an `ObjectPath`; a ValueError for a URL of another scheme."""
    if isinstance(path, ObjectPath):
        return path
    m = _URL.match(path) if isinstance(path, str) else None
    if m is None:
        return pathlib.Path(path)
    scheme, rest = m.group(1).lower(), m.group(2)
    if scheme == "file":
        return pathlib.Path(rest)
    key = rest.strip("/")
    if scheme not in SCHEMES or not key:
        raise ValueError(f"{path}: a job is a local folder or a URL s3://bucket/prefix, "
                         "gs://bucket/prefix or az://container/prefix")
    return ObjectPath(scheme, key)


# --- filesystems, from the environment ------------------------------------------------------


def _env(*names: str) -> Optional[str]:
    for name in names:
        if os.environ.get(name):
            return os.environ[name]
    return None


def _true(name: str) -> bool:
    return (os.environ.get(name) or "").strip().lower() in ("1", "true", "yes")


def _s3_endpoint() -> Optional[str]:
    return _env("AWS_ENDPOINT_URL_S3", "AWS_ENDPOINT_URL", "AWS_ENDPOINT")


def _s3(bucket: str) -> pafs.FileSystem:
    """S3, or an S3-compatible store at AWS_ENDPOINT_URL (which pyarrow's own constructor does
    not read), with path-style requests. Credentials come from the AWS SDK's usual chain."""
    options: Dict[str, object] = {}
    endpoint = _s3_endpoint()
    if endpoint:
        m = _URL.match(endpoint)
        scheme, host = (m.group(1).lower(), m.group(2)) if m else (None, endpoint)
        options["endpoint_override"] = host.rstrip("/")
        options["scheme"] = scheme or ("http" if _true("AWS_ALLOW_HTTP") else "https")
    if _true("AWS_SKIP_SIGNATURE"):
        options["anonymous"] = True
    region = _env("AWS_REGION", "AWS_DEFAULT_REGION")
    if region is None and not endpoint:
        with contextlib.suppress(OSError):
            region = pafs.resolve_s3_region(bucket)
    if region:
        options["region"] = region
    return pafs.S3FileSystem(**options)


def _gcs(bucket: str) -> pafs.FileSystem:
    """Google Cloud Storage with google-cloud-cpp's default credentials."""
    if not hasattr(pafs, "GcsFileSystem"):
        raise ValueError("gs:// needs a pyarrow built with GCS support")
    return pafs.GcsFileSystem()


def _azure(container: str) -> pafs.FileSystem:
    """Azure Blob Storage of the account AZURE_STORAGE_ACCOUNT_NAME, with its key or a SAS when
    set, else Azure's default credential chain; AZURE_STORAGE_ENDPOINT for an emulator."""
    if not hasattr(pafs, "AzureFileSystem"):
        raise ValueError("az:// needs pyarrow 16 or later (pyarrow.fs.AzureFileSystem)")
    account = _env("AZURE_STORAGE_ACCOUNT_NAME", "AZURE_STORAGE_ACCOUNT")
    if not account:
        raise ValueError(f"az://{container}: set AZURE_STORAGE_ACCOUNT_NAME (the storage account "
                         "of the container)")
    options: Dict[str, object] = {}
    if _env("AZURE_STORAGE_ACCOUNT_KEY", "AZURE_STORAGE_ACCESS_KEY"):
        options["account_key"] = _env("AZURE_STORAGE_ACCOUNT_KEY", "AZURE_STORAGE_ACCESS_KEY")
    elif _env("AZURE_STORAGE_SAS_KEY", "AZURE_STORAGE_SAS_TOKEN"):
        options["sas_token"] = _env("AZURE_STORAGE_SAS_KEY", "AZURE_STORAGE_SAS_TOKEN")
    endpoint = _env("AZURE_STORAGE_ENDPOINT")
    if endpoint:
        m = _URL.match(endpoint)
        scheme, rest = (m.group(1).lower(), m.group(2)) if m else ("https", endpoint)
        options["blob_storage_authority"] = rest.split("/", 1)[0]
        options["blob_storage_scheme"] = scheme
    return pafs.AzureFileSystem(account, **options)


_MAKERS = {"s3": _s3, "gs": _gcs, "az": _azure}

# Filesystems made in this process, by scheme, bucket and the environment they were made from
# (a forked worker makes its own: the cloud SDKs' connections do not survive a fork).
_filesystems: Dict[Tuple, pafs.FileSystem] = {}


def filesystem(path: ObjectPath) -> pafs.FileSystem:
    """The pyarrow filesystem of a bucket, made on first use from the environment."""
    env = tuple(sorted((k, v) for k, v in os.environ.items()
                       if k.startswith(("AWS_", "GOOGLE_", "AZURE_"))))
    key = (os.getpid(), path.scheme, path.bucket, env)
    fs = _filesystems.get(key)
    if fs is None:
        fs = _filesystems[key] = _MAKERS[path.scheme](path.bucket)
    return fs


def settings_hint(path: ObjectPath) -> str:
    """What the reader reads to reach a bucket of this scheme, to end an error message."""
    if path.scheme == "s3":
        endpoint = _s3_endpoint()
        return ("the reader reads AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY (or AWS_PROFILE), "
                "AWS_REGION, and AWS_ENDPOINT_URL for an S3-compatible store ("
                + (f"now {endpoint}" if endpoint else "unset: Amazon S3 itself") + ")")
    if path.scheme == "gs":
        return ("the reader reads GOOGLE_APPLICATION_CREDENTIALS (else gcloud's "
                "application-default credentials)")
    return ("the reader reads AZURE_STORAGE_ACCOUNT_NAME with AZURE_STORAGE_ACCOUNT_KEY or "
            "AZURE_STORAGE_SAS_KEY (else AZURE_CLIENT_ID, AZURE_CLIENT_SECRET, AZURE_TENANT_ID)")


def require_job(root: ObjectPath) -> None:
    """Nothing when `root/job.json` exists; else a FileNotFoundError (no such object, or no
    such bucket) or a ValueError (the store cannot be reached or refuses: credentials, endpoint)
    naming the URL and the settings the reader reads."""
    try:
        fs = filesystem(root)
        found = fs.get_file_info(f"{root.key}/job.json").type == pafs.FileType.File
        bucket = found or fs.get_file_info(root.bucket).type != pafs.FileType.NotFound
    except (OSError, ValueError) as e:
        raise ValueError(f"{root}: cannot read its job.json ({e}); "
                         f"{settings_hint(root)}") from None
    if not bucket:
        raise FileNotFoundError(f"{root}: there is no bucket {root.bucket!r}; "
                                f"{settings_hint(root)}")
    if not found:
        raise FileNotFoundError(f"{root}: no job.json there, so not a job (a job URL names the "
                                "prefix holding job.json, manifest.jsonl and shards/)")


# --- reading either kind --------------------------------------------------------------------


def _open(path: ObjectPath):
    """An input stream of an object; FileNotFoundError naming its URL when there is none."""
    try:
        return filesystem(path).open_input_stream(path.key, compression=None)
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such object") from None


def read_bytes(path: Location) -> bytes:
    """The bytes of a file or object (FileNotFoundError when absent)."""
    if isinstance(path, pathlib.Path):
        return path.read_bytes()
    with _open(path) as f:
        return f.read()


def read_text(path: Location, errors: Optional[str] = None) -> str:
    """The text of a file (in the locale's encoding, as `Path.read_text`) or of an object
    (UTF-8)."""
    if isinstance(path, pathlib.Path):
        return path.read_text(errors=errors)
    return read_bytes(path).decode("utf-8", errors=errors or "strict")


@contextlib.contextmanager
def open_text(path: Location) -> Iterator[TextIO]:
    """A file or object as UTF-8 text, streamed (a manifest may be large)."""
    if isinstance(path, pathlib.Path):
        with open(path, encoding="utf-8") as f:
            yield f
        return
    with _open(path) as raw, io.TextIOWrapper(raw, encoding="utf-8") as f:
        yield f


def sha256(path: Location) -> str:
    """Hex sha256 of a file's or object's bytes, streamed in 4 MiB blocks."""
    h = hashlib.sha256()
    with (open(path, "rb") if isinstance(path, pathlib.Path) else _open(path)) as f:
        while block := f.read(4 << 20):
            h.update(block)
    return h.hexdigest()


def stamp(path: Location) -> Tuple[int, int, int, int]:
    """(size, mtime_ns, ctime_ns, inode) of a file; of an object (size, mtime_ns, 0, 0), the
    modification time by the store's clock. FileNotFoundError when absent."""
    if isinstance(path, pathlib.Path):
        st = os.stat(path)
        return st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino
    info = filesystem(path).get_file_info(path.key)
    if info.type != pafs.FileType.File:
        raise FileNotFoundError(f"{path}: no such object")
    return info.size or 0, info.mtime_ns or 0, 0, 0


def exists(path: Location) -> bool:
    """Whether a file, folder, object or prefix is there."""
    if isinstance(path, pathlib.Path):
        return path.exists()
    return filesystem(path).get_file_info(path.key).type != pafs.FileType.NotFound


def entries(folder: Location) -> List[Location]:
    """What a folder (or prefix) holds, files and folders, sorted; [] when it does not exist."""
    if isinstance(folder, pathlib.Path):
        return sorted(folder.iterdir()) if folder.is_dir() else []
    selector = pafs.FileSelector(folder.key, allow_not_found=True)
    found = filesystem(folder).get_file_info(selector)
    return sorted((folder / info.base_name for info in found), key=str)


def parquet_names(folder: Location) -> List[str]:
    """Names of the `*.parquet` entries of a folder (or files directly under a prefix)."""
    if isinstance(folder, pathlib.Path):
        return [p.name for p in folder.glob("*.parquet")]
    selector = pafs.FileSelector(folder.key, allow_not_found=True)
    return [info.base_name for info in filesystem(folder).get_file_info(selector)
            if info.type == pafs.FileType.File and info.base_name.endswith(".parquet")]


def parquet_file(path: Location) -> pq.ParquetFile:
    """A Parquet file on disk, or an object read by ranges (column chunks fetched together)."""
    if isinstance(path, pathlib.Path):
        return pq.ParquetFile(path)
    try:
        source = filesystem(path).open_input_file(path.key)
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such object") from None
    return pq.ParquetFile(source, pre_buffer=True)
