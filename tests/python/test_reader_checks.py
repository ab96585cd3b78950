"""The Python reader reads a job the way the CLI does (docs/RELIABILITY.md, "The Python
reader"): only the job's own shards, only those whose completion record the file matches (the
sha256 by default), every row its shard's item, a `ShardWarning` naming each shard left out (not
finished, damaged, moved to quarantine/, a stray file), and a missing column named."""

import json
import os
import re
import shutil
import sys
import warnings
import weakref

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from sparc3d_cli import ROOT, rewrite_slice, run

try:
    import sparc3d_reader as reader
except ImportError:  # not installed (`pip install ./python`): use the checkout
    if os.environ.get("SPARC3D_CI") == "1":
        raise
    sys.path.insert(0, str(ROOT / "python"))
    import sparc3d_reader as reader

MESHES = ["sphere.obj", "cube.off", "cube_binary.ply", "wuson.stl", "box_textured.glb"]
ITEMS = 10  # shard size 3: shards of items 0-2, 3-5, 6-8 and 9
IDS = ["item%02d" % i for i in range(ITEMS)]
MODES = [True, "quick", False]


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("reader-checks")
    manifest = tmp / "m.jsonl"
    manifest.write_text("".join(
        json.dumps({"id": IDS[i], "uri": str(ROOT / "examples" / MESHES[i % 5])}) + "\n"
        for i in range(ITEMS)))
    job = tmp / "job"
    run("init", job, "--manifest", manifest, "--resolution", 32, "--shard-size", 3)
    run("run", job, "--workers", 2)
    return job


@pytest.fixture
def job(clean, tmp_path):
    """A fresh copy of the clean job, to damage."""
    copy = tmp_path / "job"
    shutil.copytree(clean, copy)
    return copy


def ids_read(job, verify=True, expect_warning=None):
    """Ids of the items `iter_items` and `SparseCubesDataset` read (they must agree), and the
    ShardWarning messages of the first."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ids = [it["id"] for it in reader.iter_items(job, verify=verify)]
        ds = reader.SparseCubesDataset(job, verify=verify)
    assert ds.ids == ids and [ds[i]["id"] for i in range(len(ds))] == ids
    msgs = [str(w.message) for w in caught if issubclass(w.category, reader.ShardWarning)]
    if expect_warning is not None:
        assert any(re.search(expect_warning, m) for m in msgs), msgs
    return ids, msgs


def test_the_clean_job_reads_whole_without_a_warning(clean):
    for verify in MODES:
        ids, msgs = ids_read(clean, verify)
        assert ids == IDS and msgs == []


@pytest.mark.parametrize("verify", MODES)
def test_each_shard_is_opened_once_on_the_way_to_its_rows(clean, verify, monkeypatch):
    """The open that checks a shard (its footer's fingerprint, its rows against the frozen
    manifest) is the one its rows are read from: reading the job opens each shard's Parquet
    file once, and building a dataset (checks, then its index) opens each once too. The
    readers that go shard by shard keep one file open at a time."""
    opened, alive, most = [], weakref.WeakSet(), [0]

    class Counted(pq.ParquetFile):
        def __init__(self, source, *args, **kwargs):
            opened.append(os.path.basename(str(source)))
            super().__init__(source, *args, **kwargs)
            alive.add(self)
            most[0] = max(most[0], len(alive))

    monkeypatch.setattr(pq, "ParquetFile", Counted)
    shards = ["part-%05d.parquet" % n for n in range(4)]
    reads = {  # reader: (what it reads, the most files it may hold open at once)
        "iter_items": (lambda: [it["id"] for it in reader.iter_items(clean, verify=verify)], 1),
        "iter_tensor_rows": (lambda: [r["id"] for r in reader.iter_tensor_rows(
            clean, ["sdf"], verify=verify)], 1),
        "shard_paths": (lambda: reader.shard_paths(clean, verify=verify) and IDS, 1),
        "SparseCubesDataset": (lambda: reader.SparseCubesDataset(clean, verify=verify).ids, 4),
        "StreamingDataset": (lambda: len(reader.StreamingDataset(clean, verify=verify)) and IDS, 4),
    }
    for name, (read, held) in reads.items():
        opened.clear()
        most[0] = 0
        assert read() == IDS, name
        assert sorted(opened) == shards, (name, opened)
        assert most[0] <= held, (name, most[0])


@pytest.mark.parametrize("verify", MODES)
def test_a_shard_restored_into_another_slot_is_not_read(job, verify):
    shards = job / "shards"
    shutil.copy(shards / "part-00001.parquet", shards / "part-00000.parquet")
    ids, msgs = ids_read(job, verify, expect_warning=r"has \d+ bytes, its completion record says \d+")
    assert ids == IDS[3:]  # shard 0 left out: nothing twice, nothing under another's slot
    assert "part-00000.parquet" in msgs[0] and "sparc3d verify" in msgs[0]


def test_a_pair_restored_into_another_slot_is_not_read(job):
    shards = job / "shards"
    for ext in (".parquet", ".complete.json"):
        shutil.copy(shards / ("part-00001" + ext), shards / ("part-00000" + ext))
    for verify in MODES:
        ids, _ = ids_read(job, verify, expect_warning="part-00000.parquet .*its completion record is shard 1's")
        assert ids == IDS[3:]
    # The record edited to claim slot 0: the rows still tell.
    path = shards / "part-00000.complete.json"
    path.write_text(path.read_text().replace('"shard": 1', '"shard": 0'))
    for verify in MODES:
        ids, _ = ids_read(job, verify, expect_warning="its rows are items 3–5, shard 0 holds items 0–2")
        assert ids == IDS[3:]


def test_a_stray_pair_is_ignored_and_named(job):
    shards = job / "shards"
    for ext in (".parquet", ".complete.json"):
        shutil.copy(shards / ("part-00001" + ext), shards / ("part-00099" + ext))
    shutil.copy(shards / "part-00002.parquet", shards / "part-00002 (copy).parquet")
    ids, msgs = ids_read(job, expect_warning=re.escape("ignored part-00002 (copy).parquet, part-00099.parquet"))
    assert ids == IDS
    assert "not one of the job's 4 shards (part-00000.parquet … part-00003.parquet)" in msgs[0]


def test_unfinished_and_quarantined_shards_are_named(job):
    # Shard 2's file damaged (a byte flipped): `verify` moves it into quarantine/; shard 3's
    # record deleted (not finished).
    path = job / "shards" / "part-00002.parquet"
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x10
    path.write_bytes(bytes(data))
    assert run("verify", job, check=False).returncode == 1
    (job / "shards" / "part-00003.complete.json").unlink()
    folder = next((job / "quarantine").iterdir()).name
    assert folder.startswith("part-00002-")
    ids, msgs = ids_read(job, expect_warning="2 of 4 shards are not read")
    assert ids == IDS[:6]
    assert (f"part-00002.parquet: not finished; moved aside to quarantine/{folder} "
            f"(shard 2: {path} has sha256") in msgs[0], msgs[0]
    assert "part-00003.parquet: not finished" in msgs[0] and "sparc3d run" in msgs[0]
    # As errors, for whoever wants every item or none.
    with warnings.catch_warnings():
        warnings.simplefilter("error", reader.ShardWarning)
        with pytest.raises(reader.ShardWarning, match="part-00002"):
            reader.shard_paths(job)


def test_a_torn_record_and_a_missing_file_are_damage(job):
    (job / "shards" / "part-00001.complete.json").write_text('{"shard": 1, "finger')
    (job / "shards" / "part-00002.parquet").unlink()
    ids, msgs = ids_read(job, expect_warning="part-00001.parquet: damaged, its completion record .* does not parse")
    assert ids == IDS[:3] + IDS[9:]
    assert any("part-00002.parquet is missing" in m for m in msgs), msgs


def test_a_record_of_another_config_is_refused(job):
    path = job / "shards" / "part-00001.complete.json"
    record = json.loads(path.read_text())
    record["fingerprint"] = "0" * 64
    path.write_text(json.dumps(record))
    with pytest.raises(ValueError, match="part-00001.parquet.*another config"):
        list(reader.iter_items(job))


def test_rows_that_are_not_the_manifests_items_are_not_read(job):
    # A shard of another job with the same config and item count but other ids, restored with
    # its record: the record matches the file, only the manifest tells.
    # Item 4 is in shard 1 (shards of 3); its slice is replaced and pinned as by another init.
    rewrite_slice(job, 1, lambda text: text.replace("item04", "other4"))
    for verify in MODES:
        ids, _ = ids_read(job, verify, expect_warning=re.escape("row of item 4 ('item04'): the manifest says id 'other4'"))
        assert ids == IDS[:3] + IDS[6:]


def _chunk_bytes(path, names):
    """Byte offsets of the column chunks `names` of the first row group."""
    rg = pq.ParquetFile(path).metadata.row_group(0)
    out = []
    for i in range(rg.num_columns):
        c = rg.column(i)
        if c.path_in_schema in names:
            start = c.dictionary_page_offset or c.data_page_offset
            out.extend(range(start, start + c.total_compressed_size))
    return out


@pytest.mark.parametrize("verify", [True, "quick"])
def test_bit_flips_in_scale_and_center_never_read_as_other_numbers(job, verify):
    """Every single-bit flip in the `scale` and `center_*` column chunks of a shard (pages
    without a checksum of their own): with the default verification the shard is left out
    with a warning, never read with other numbers."""
    path = job / "shards" / "part-00000.parquet"
    clean = path.read_bytes()
    want = [(it["scale"], it["center"].tolist()) for it in reader.iter_items(path)]
    offsets = _chunk_bytes(path, {"scale", "center_x", "center_y", "center_z"})
    assert len(offsets) > 200
    left_out = 0
    for n, offset in enumerate(offsets):
        data = bytearray(clean)
        data[offset] ^= 1 << (n % 8)  # one bit per byte, each bit position in turn
        path.write_bytes(bytes(data))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            got = [(it["scale"], it["center"].tolist()) for it in reader.iter_items(path, verify=verify)]
        assert got in ([], want), (offset, got)
        left_out += got == [] and any(issubclass(w.category, reader.ShardWarning) for w in caught)
    assert left_out == len(offsets)
    path.write_bytes(clean)


def test_without_verification_damaged_dtype_and_shape_pages_never_read_as_other_items(job):
    """verify=False skips the sha256, not the other checks: single-bit flips all over the
    `coords_dtype` and `coords_shape` column chunks either raise an error naming the shard or
    reads the exact items; never fewer items (pyarrow reads a chunk with a damaged page header
    as no rows, silently) nor other numbers."""
    path = job / "shards" / "part-00000.parquet"
    clean = path.read_bytes()
    want = list(reader.iter_items(path))
    offsets = _chunk_bytes(path, {"coords_dtype", "coords_shape.list.item"})
    silent_in_pyarrow = 0
    for n, offset in enumerate(offsets):
        for bit in (n % 8, (n + 3) % 8):  # two bits per byte, every position in turn
            data = bytearray(clean)
            data[offset] ^= 1 << bit
            path.write_bytes(bytes(data))
            try:
                silent_in_pyarrow += pq.read_table(path, columns=["coords_dtype"]).num_rows == 0
            except Exception:
                pass
            try:
                got = list(reader.iter_items(path, verify=False))
            except ValueError as e:
                assert str(path) in str(e)
                continue
            assert [g["id"] for g in got] == [w["id"] for w in want], (offset, bit)
            for g, w in zip(got, want):
                for name in reader.TENSORS:
                    np.testing.assert_array_equal(g[name], w[name])
    assert silent_in_pyarrow > 0  # the case the row count check is for did occur
    path.write_bytes(clean)


def test_a_byte_order_flip_in_a_dtype_is_refused(clean, tmp_path):
    src = clean / "shards" / "part-00000.parquet"
    f = pq.ParquetFile(src)
    table = f.read()
    dtypes = table.column("sdf_dtype").to_pylist()
    assert dtypes[0] == "<f4"
    swapped = table.set_column(table.schema.get_field_index("sdf_dtype"), "sdf_dtype",
                               pa.array([">f4"] + dtypes[1:]))
    out = tmp_path / "part-00000.parquet"
    pq.write_table(swapped.replace_schema_metadata(f.metadata.metadata), out)
    with pytest.raises(ValueError, match=r"item 'item00': column sdf_dtype is '>f4', not a little-endian"):
        list(reader.iter_items(out))


def test_a_missing_column_is_named(clean, tmp_path):
    src = clean / "shards" / "part-00000.parquet"
    f = pq.ParquetFile(src)
    cut = tmp_path / "part-00000.parquet"
    pq.write_table(f.read().drop_columns(["scale"]).replace_schema_metadata(f.metadata.metadata), cut)
    with pytest.raises(ValueError, match=r"part-00000.parquet: no column 'scale'"):
        list(reader.iter_items(cut))
    with pytest.raises(ValueError, match=r"no column 'scale'"):
        reader.SparseCubesDataset(cut)[0]
    with pytest.raises(ValueError, match=r"no column 'sfd', 'sfd_dtype', 'sfd_shape'"):
        list(reader.iter_tensor_rows(src, ["sfd"]))
    row = f.read().to_pylist()[0]
    del row["center_y"]
    with pytest.raises(ValueError, match=r"item 'item00': no column 'center_y'"):
        reader.row_to_item(row)


def test_a_dataset_notices_a_shard_changed_under_it(job):
    ds = reader.SparseCubesDataset(job)
    path = job / "shards" / "part-00001.parquet"
    # Touched, bytes unchanged (copied back, say): still read.
    path.write_bytes(path.read_bytes())
    assert ds[3]["id"] == IDS[3] and ds[0]["id"] == IDS[0]
    # Replaced by another shard's bytes: an error, not another item under this index.
    shutil.copy(job / "shards" / "part-00002.parquet", path)
    with pytest.raises(ValueError, match="part-00001.parquet changed since it was checked"):
        ds[4]
