"""`where="..."` filters on the shards' scalar columns, the language of the binary's `--where`
(manifests/src/filter: `sparc3d init`, `export`, `ls`, `inspect`):

    license in (cc-by, cc0)        input_faces <= 1000000 and license in (cc0, cc-by)
    resolution = 256               source != sketchfab and license not in ('by-nc', "by-nc-sa")

Conditions are joined by the word `and` (any case). A condition is `column OP value` with OP one
of `=`, `!=`, `<`, `<=`, `>`, `>=`, or `column in (v, ...)` / `column not in (v, ...)`. Values
are bare words (no spaces, commas, parentheses, quotes, `=`, `!`, `<`, `>`) or quoted with `'`
or `"`. A column name that is not a shard column but whose provenance column
`manifest.<name>` is (`license` for `manifest.license`) refers to that one. The messages are
the binary's (manifests/src/filter/), in Python's quoting.

`=`, `!=` and `in` compare as text, except on a column that is numeric in the shard (integers
or floats), where both sides compare as numbers (`resolution = 256` matches 256.0) and a value
that is not a number is refused, naming it. `<`, `<=`, `>`, `>=` need a number on the right
and a numeric column; either missing is a ValueError naming the value or the column. Numbers
are read as the binary reads them (`1000000`, `0.5`, `-3`, `1e6`, `inf`; never NaN). A null
(no value in the row, or a column this row's shard lacks) satisfies no comparison but does
satisfy `!=` and `not in`. A column no shard has is refused, naming the columns there are.
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple, Union

import pyarrow as pa

#: The comparison marks, longest first so that `<=` is not read as `<` then `=`.
_MARKS = ("!=", "<=", ">=", "=", "<", ">", "(", ")", ",")
#: The marks that order numbers.
_ORDERINGS = ("<", "<=", ">", ">=")
#: Characters that end a bare word.
_WORD_END = re.compile(r"[\s(),=!<>'\"]")

Number = Union[int, float]


@dataclasses.dataclass(frozen=True)
class _Token:
    """A word (bare or quoted) or a mark."""

    text: str
    kind: str  # "word", "quoted" or "mark"

    def said(self) -> str:
        """The token in plain words, for a parse error."""
        if self.kind == "quoted":
            return f"the quoted value {self.text!r}"
        return f"the word {self.text!r}" if self.kind == "word" else f"`{self.text}`"


def _tokens(text: str) -> List[_Token]:
    """Splits a filter into words, quoted values and marks."""
    out, i = [], 0
    while i < len(text):
        c = text[i]
        if c.isspace():
            i += 1
        elif c in "'\"":
            end = text.find(c, i + 1)
            if end < 0:
                raise ValueError(f"--where {text!r}: a quote {c} is not closed")
            out.append(_Token(text[i + 1:end], "quoted"))
            i = end + 1
        elif c in "(),=!<>":
            mark = next((m for m in _MARKS if text.startswith(m, i)), None)
            if mark is None:
                raise ValueError(f"--where {text!r}: `!` must be followed by `=`")
            out.append(_Token(mark, "mark"))
            i += len(mark)
        else:
            m = _WORD_END.search(text, i)
            end = m.start() if m else len(text)
            out.append(_Token(text[i:end], "word"))
            i = end
    return out


def number(text: str) -> Optional[Number]:
    """`text` as a number, as the binary reads one (Rust's `f64` parse of the trimmed text:
    `1000000`, `0.5`, `-3`, `1e6`, `inf`), an int when it is digits only; None when it is not a
    number, and for NaN, which orders with nothing."""
    t = text.strip()
    if re.fullmatch(r"[+-]?\d+", t):
        return int(t)
    if "_" in t:  # Python's float reads `1_000`, Rust's does not
        return None
    try:
        x = float(t)
    except ValueError:
        return None
    return None if math.isnan(x) else x


@dataclasses.dataclass(frozen=True)
class Condition:
    """`column OP values`: OP one of `=`, `!=`, `<`, `<=`, `>`, `>=`, `in`, `not in`."""

    column: str
    op: str
    values: Tuple[str, ...]

    @property
    def negated(self) -> bool:
        """`!=` and `not in`: satisfied by a null."""
        return self.op in ("!=", "not in")


class _Parser:
    """Reads the tokens of one filter in order."""

    def __init__(self, text: str):
        self.text, self.tokens, self.at = text, _tokens(text), 0

    def fail(self, expected: str, found: Optional[_Token]) -> ValueError:
        said = found.said() if found else "the end of the filter"
        return ValueError(f"--where {self.text!r}: expected {expected}, found {said}")

    def next(self) -> Optional[_Token]:
        t = self.tokens[self.at] if self.at < len(self.tokens) else None
        self.at += 1
        return t

    def word(self, what: str) -> str:
        t = self.next()
        if t is None or t.kind == "mark":
            raise self.fail(what, t)
        return t.text

    def ordered(self, column: str, op: str) -> str:
        """The number after an ordering operator; a ValueError names a value that is not one."""
        value = self.word("a number")
        if number(value) is None:
            raise ValueError(f"--where {self.text!r}: `{column} {op} {value}`: {value!r} is not "
                             f"a number ({op} compares numbers)")
        return value

    def values(self) -> Tuple[str, ...]:
        """`( v, v, ... )`."""
        t = self.next()
        if t is None or t.text != "(" or t.kind != "mark":
            raise self.fail("`(`", t)
        values = [self.word("a value")]
        while True:
            t = self.next()
            if t is not None and t.kind == "mark" and t.text == ")":
                return tuple(values)
            if t is None or t.kind != "mark" or t.text != ",":
                raise self.fail("`,` or `)`", t)
            values.append(self.word("a value"))

    def condition(self) -> Condition:
        column = self.word("a column name").lower()
        t = self.next()
        if t is not None and t.kind == "mark" and t.text in ("=", "!="):
            return Condition(column, t.text, (self.word("a value"),))
        if t is not None and t.kind == "mark" and t.text in _ORDERINGS:
            return Condition(column, t.text, (self.ordered(column, t.text),))
        if _keyword(t, "in"):
            return Condition(column, "in", self.values())
        if _keyword(t, "not"):
            after = self.next()
            if not _keyword(after, "in"):
                raise self.fail("`in` after `not`", after)
            return Condition(column, "not in", self.values())
        raise self.fail(f"`=`, `!=`, `<`, `<=`, `>`, `>=`, `in` or `not in` after {column}", t)


def _keyword(t: Optional[_Token], kw: str) -> bool:
    return t is not None and t.kind == "word" and t.text.lower() == kw


@dataclasses.dataclass(frozen=True)
class Where:
    """A parsed filter: every condition must hold. `Where.parse(text)` reads one; `bind`
    checks it against the shards' columns; `keep` evaluates it on a table of rows."""

    text: str
    conditions: Tuple[Condition, ...]

    @staticmethod
    def parse(text: str) -> "Where":
        """Parses a filter as the module says; a ValueError names what is wrong in it."""
        p = _Parser(text)
        conditions = [p.condition()]
        while p.at < len(p.tokens):
            joint = p.next()
            if not _keyword(joint, "and"):
                said = joint.said() if joint else "the end of the filter"
                raise ValueError(f"--where {text!r}: conditions are joined by `and`, found {said}")
            conditions.append(p.condition())
        return Where(text, tuple(conditions))

    def bind(self, schemas: Sequence[pa.Schema]) -> "BoundWhere":
        """The filter with each column named as the shards name it (`license` →
        `manifest.license` where only that exists), checked against the shards' schemas: a
        column no shard has, a column that is not scalar, or a non-numeric column (or value)
        where numbers are needed is a ValueError naming it."""
        if not schemas:  # no shard to read: nothing to check against, nothing kept
            return BoundWhere(self, {c.column: c.column for c in self.conditions})
        columns = {}
        for c in self.conditions:
            name = _resolve(c.column, schemas)
            if name is None:
                names = dict.fromkeys(_named(n, s) for s in schemas for n in scalar_columns(s))
                raise ValueError(f"--where: the shards have no column {c.column!r} (their "
                                 f"columns: {', '.join(names)})")
            types = [s.field(name).type for s in schemas if name in s.names]
            _check_types(c, name, types)
            columns[c.column] = name
        return BoundWhere(self, columns)


def _resolve(column: str, schemas: Sequence[pa.Schema]) -> Optional[str]:
    """The shard column a filter's column names: itself, else its provenance column."""
    for name in (column, "manifest." + column):
        if any(name in s.names for s in schemas):
            return name
    return None


def _named(column: str, schema: pa.Schema) -> str:
    """How a filter names a shard column: a provenance column by its bare name, unless the
    shard has a column of that name itself."""
    bare = column[len("manifest."):] if column.startswith("manifest.") else None
    return bare if bare and bare not in schema.names else column


def scalar_columns(schema: pa.Schema) -> List[str]:
    """The columns a filter can use: text, numbers and booleans, without the `_dtype` of a
    tensor (a binary column beside it)."""
    binary = {f.name for f in schema
              if pa.types.is_binary(f.type) or pa.types.is_large_binary(f.type)}
    return [f.name for f in schema if _scalar(f.type) and not (
        f.name.endswith("_dtype") and f.name[: -len("_dtype")] in binary)]


def _scalar(t: pa.DataType) -> bool:
    return (pa.types.is_string(t) or pa.types.is_large_string(t) or pa.types.is_boolean(t)
            or _numeric(t))


def _numeric(t: pa.DataType) -> bool:
    return pa.types.is_integer(t) or pa.types.is_floating(t)


def _check_types(c: Condition, name: str, types: List[pa.DataType]) -> None:
    """A ValueError when the column is not scalar in some shard, or is not numeric where the
    condition needs numbers, or the condition's values are not numbers on a numeric column."""
    if not all(_scalar(t) for t in types):
        raise ValueError(f"--where: column {name!r} is not a scalar column (a tensor or a list); "
                         "a filter compares text, numbers and booleans")
    numeric = [_numeric(t) for t in types]
    if c.op in _ORDERINGS and not all(numeric):
        raise ValueError(f"--where: `{c.column} {c.op} {c.values[0]}`: the column {name} holds "
                         f"{types[numeric.index(False)]}, and `{c.op}` compares numbers")
    bad = [v for v in c.values if number(v) is None]
    if any(numeric) and bad:
        raise ValueError(f"--where: the column {name} holds numbers, and {bad[0]!r} is not a "
                         "number")


@dataclasses.dataclass(frozen=True)
class BoundWhere:
    """A filter bound to the shards' column names (`Where.bind`)."""

    where: Where
    #: Each condition's column → the shard column it reads.
    names: Dict[str, str]

    def columns(self, schema: pa.Schema) -> List[str]:
        """The columns of a shard with this schema that the filter reads."""
        return sorted({n for n in self.names.values() if n in schema.names})

    def keep(self, table: pa.Table) -> List[bool]:
        """Whether each row of `table` (read with at least `columns(...)` of its shard)
        passes every condition; a column the table lacks is null in every row."""
        keep = [True] * table.num_rows
        for c in self.where.conditions:
            name = self.names[c.column]
            if name not in table.column_names:
                values: Iterable[Any] = [None] * table.num_rows
                numeric = False
            else:
                values = table.column(name).to_pylist()
                numeric = _numeric(table.schema.field(name).type)
            test = _test(c, numeric)
            keep = [k and test(v) for k, v in zip(keep, values)]
        return keep


def _test(c: Condition, numeric: bool):
    """A function of one cell's value: whether it passes condition `c`."""
    wanted = [number(v) if numeric else v for v in c.values]
    if c.op in _ORDERINGS:
        bound = wanted[0] if numeric else number(c.values[0])
        compare = {"<": lambda v: v < bound, "<=": lambda v: v <= bound,
                   ">": lambda v: v > bound, ">=": lambda v: v >= bound}[c.op]
        return lambda v: v is not None and compare(v)

    def found(v: Any) -> bool:
        text = v if numeric or isinstance(v, str) else _text(v)
        return any(text == w for w in wanted)

    return lambda v: c.negated if v is None else found(v) != c.negated


def _text(v: Any) -> str:
    """A non-text, non-numeric cell as text (a boolean as `true` / `false`)."""
    return ("true" if v else "false") if isinstance(v, bool) else str(v)
