"""`where="..."` filters (issue 44, item 3, the reader's side): the binary's `--where` language
with numeric comparisons, on the shards' scalar columns. Checked against answers computed by
hand from the manifest and the mesh files (not read from the shards), through both datasets;
null and missing-column semantics on tables; parse errors and refusals named."""

import os
import sys

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from sparc3d_cli import ROOT
from stream_jobs import IDS, LICENSES, MESHES, caption, make_job, triangles

try:
    import sparc3d_reader as reader
except ImportError:  # not installed (`pip install ./python`): use the checkout
    if os.environ.get("SPARC3D_CI") == "1":
        raise
    sys.path.insert(0, str(ROOT / "python"))
    import sparc3d_reader as reader

from sparc3d_reader.where import Where


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    return make_job(tmp_path_factory.mktemp("where"))


def selected(job, where):
    """Ids the filter keeps, in job order: both datasets must agree."""
    ds = reader.SparseCubesDataset(job, where=where)
    streamed = [it["id"] for it in reader.StreamingDataset(job, where=where, shuffle=False)]
    assert ds.ids == streamed and [ds[i]["id"] for i in range(len(ds))] == streamed
    return streamed


def faces(i):
    return triangles(MESHES[i % 5])


EXPECTED = [
    ("license = cc0", lambda i: LICENSES[i % 3] == "cc0"),
    ("manifest.license != cc0", lambda i: LICENSES[i % 3] != "cc0"),
    ("LICENSE in (cc0, 'cc-by') AND input_faces <= 12",
     lambda i: LICENSES[i % 3] in ("cc0", "cc-by") and faces(i) <= 12),
    ("input_faces > 2000", lambda i: faces(i) > 2000),
    ("input_faces >= 1792 and input_faces < 3732", lambda i: 1792 <= faces(i) < 3732),
    ("input_faces in (12, 3732.0)", lambda i: faces(i) in (12, 3732)),
    ("input_faces not in (12)", lambda i: faces(i) != 12),
    ("resolution = 32.0", lambda i: True),
    ("resolution in (16, 32)", lambda i: True),
    ("resolution != 32", lambda i: False),
    ("caption = 'a thing'", lambda i: caption(i) == "a thing"),
    ("caption != \"a thing\"", lambda i: caption(i) is None),
    ("caption not in ('a thing', other)", lambda i: caption(i) is None),
    ("caption = ''", lambda i: False),  # a null satisfies no comparison
    ("year = 2003", lambda i: i == 3),  # a text column: compared as text
    ("id in (it01, \"it05\", broken)", lambda i: i in (1, 5)),  # the failed row never
]


@pytest.mark.parametrize("where,keep", EXPECTED, ids=[w for w, _ in EXPECTED])
def test_filters_keep_the_hand_computed_items(job, where, keep):
    assert selected(job, where) == [IDS[i] for i in range(len(IDS)) if keep(i)]


def test_filters_read_only_the_scalar_columns(job, monkeypatch):
    read = []
    real = pq.ParquetFile.read_row_group
    monkeypatch.setattr(pq.ParquetFile, "read_row_group",
                        lambda self, g, columns=None, **kw: read.append(columns) or real(
                            self, g, columns=columns, **kw))
    reader.StreamingDataset(job, where="input_faces <= 12 and license = cc0")
    assert read and all(set(c) == {"id", "status", "input_faces", "manifest.license"} for c in read)


@pytest.mark.parametrize("where,said", [
    ("licence = cc0", "the shards have no column 'licence' (their columns: "),
    ("coords = x", "column 'coords' is not a scalar column"),
    ("year < 2005", "`year < 2005`: the column manifest.year holds string, and `<` compares "
                    "numbers"),
    ("resolution = abc", "the column resolution holds numbers, and 'abc' is not a number"),
    ("resolution in (32, x32)", "'x32' is not a number"),
])
def test_refusals_name_the_column_or_value(job, where, said):
    with pytest.raises(ValueError, match=said.replace("(", r"\(")) as e:
        reader.StreamingDataset(job, where=where)
    if "their columns" in said:  # the scalar columns, provenance ones by their shard name
        listed = str(e.value).split("their columns: ")[1]
        names = listed.rstrip(")").split(", ")
        assert "input_faces" in names and "license" in names and "caption" in names
        assert "manifest.license" not in names and "coords_dtype" not in names
    with pytest.raises(ValueError, match=said.replace("(", r"\(")):
        reader.SparseCubesDataset(job, where=where)


@pytest.mark.parametrize("text,said", [
    ("license", "expected `=`, `!=`, `<`, `<=`, `>`, `>=`, `in` or `not in` after license, "
                "found the end of the filter"),
    ("license in cc0", "expected `(`, found the word 'cc0'"),
    ("license in (cc0", "expected `,` or `)`, found the end of the filter"),
    ("license in (cc0 'by')", "expected `,` or `)`, found the quoted value 'by'"),
    ("license = 'cc0", "a quote ' is not closed"),
    ("license = cc0 or source = a", "conditions are joined by `and`, found the word 'or'"),
    ("license ! cc0", "`!` must be followed by `=`"),
    ("license not (cc0)", "expected `in` after `not`, found `(`"),
    ("= cc0", "expected a column name, found `=`"),
    ("", "expected a column name, found the end of the filter"),
    ("input_faces < many", "`input_faces < many`: 'many' is not a number (< compares numbers)"),
    ("input_faces <= 'ten'", "'ten' is not a number"),
    ("aspect > nan", "'nan' is not a number"),
    ("input_faces >= 1e", "'1e' is not a number"),
    ("aspect >", "expected a number, found the end of the filter"),
    ("aspect < (1, 2)", "expected a number, found `(`"),
    ("a => 3", "expected a value, found `>`"),
])
def test_parse_errors_say_what_was_found(text, said):
    with pytest.raises(ValueError, match=r"^--where .*" + _escaped(said)):
        Where.parse(text)


def _escaped(text):
    import re

    return re.escape(text)


def test_nulls_numbers_and_missing_columns_on_a_table():
    table = pa.table({
        "n": pa.array([1, None, 3, 256], type=pa.uint64()),
        "x": pa.array([0.5, 2.0, None, 256.0]),
        "s": pa.array(["a", None, "b", "256"]),
        "b": pa.array([True, False, None, True]),
    })
    other = pa.schema([("m", pa.string())])  # a second shard with another column only

    def keep(text):
        return Where.parse(text).bind([table.schema, other]).keep(table)

    assert keep("n >= 1") == [True, False, True, True]
    assert keep("n != 1") == [False, True, True, True]
    assert keep("n not in (1, 3)") == [False, True, False, True]
    assert keep("x = 2") == [False, True, False, False]
    assert keep("x in (2, 256)") == [False, True, False, True]
    assert keep("x < 1 and n = 1") == [True, False, False, False]
    assert keep("s = 256") == [False, False, False, True]  # text: '256' only
    assert keep("s != a") == [False, True, True, True]
    assert keep("b = true") == [True, False, False, True]
    # `m` is in the other shard only: null in every row of this one.
    assert keep("m = a") == [False] * 4 and keep("m != a") == [True] * 4
    assert keep("m not in (a)") == [True] * 4
    assert keep("n < inf") == [True, False, True, True]  # numbers as the binary reads them
    assert keep("x >= 1e2") == [False, False, False, True]
    with pytest.raises(ValueError, match="the column s holds string"):
        keep("s > 1")
    with pytest.raises(ValueError, match=r"the shards have no column 'z' \(their columns: n, x, s, b, m\)"):
        keep("z = 1")
