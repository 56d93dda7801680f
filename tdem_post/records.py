"""Records: a producer's result as one frozen dataclass, units in its field names (issue 26).

One serializer writes a record from its fields (``dataclasses.fields`` / ``asdict``), one reader
reads it back into its dataclass:

    write_json(path, record)            record_from_json(cls, path) -> record
    json_text(record) -> str
    to_dict(record) -> dict             from_dict(cls, data, where) -> record
    write_csv(path, records)            read_csv(cls, path) -> [record, ...]
    markdown_table(records) -> [line, ...]

The reader refuses, in one line naming the file and the field, a field that is missing (renamed
by a newer writer, or misspelt), one it does not know, and a value of another type: never a NaN
column. JSON keeps nested records, tuples and dicts; a CSV row is a flat record (numbers, strings,
None as an empty cell, NaN as an empty cell of a float column).

Field metadata (:func:`column`) says how a field shows in a markdown table (its place, heading
and cell text) and whether it is ``optional``: left out of the JSON when None (and absent read as
None), its CSV column left out when no row has a value.
"""
from __future__ import annotations

import dataclasses
import difflib
import json
import math
import types
import typing
from pathlib import Path

from thermal_kernel.atomic import replacing, write_text_atomic


class RecordError(ValueError):
    """A record file that does not hold its record: one line naming the file and the field."""


def column(*, md: tuple | None = None, optional: bool = False) -> dict:
    """Metadata of a record field: ``md = (place, heading, cell)`` puts it in
    :func:`markdown_table` (``place`` sorts the columns, ``cell(record) -> str`` its text);
    ``optional``: left out of the JSON when None (absent: read as None), its CSV column left out
    when every row's value is None."""
    return {"md": md, "optional": optional}


def to_dict(record) -> dict:
    """The record as plain JSON data (nested records as dicts), field by field in their order;
    an optional field that is None is left out."""
    return {f.name: _plain(getattr(record, f.name)) for f in dataclasses.fields(record)
            if not (f.metadata.get("optional") and getattr(record, f.name) is None)}


def _plain(v):
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return to_dict(v)
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    return v


def json_text(record) -> str:
    """The record's JSON text (one field per key, indented by one)."""
    return json.dumps(to_dict(record), indent=1)


def write_json(path: Path, record) -> None:
    write_text_atomic(Path(path), json_text(record))


def record_from_json(cls, path: Path):
    """The ``cls`` record stored in ``path`` (:func:`write_json`); RecordError in one line."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise RecordError(f"{path}: expected a JSON {cls.__name__} record ({e})") from None
    return from_dict(cls, data, str(path))


def from_dict(cls, data, where: str):
    """``cls`` from ``data``: every field present, none unknown, each value of its type."""
    if not isinstance(data, dict):
        raise RecordError(f"{where}: expected a {cls.__name__} record (an object), got "
                          f"{type(data).__name__}")
    fields = [f for f in dataclasses.fields(cls) if f.init]
    names = [f.name for f in fields]
    missing = [f.name for f in fields if f.name not in data and not f.metadata.get("optional")]
    unknown = [k for k in data if k not in names]
    if missing:
        near = difflib.get_close_matches(missing[0], unknown, n=1)
        raise RecordError(f"{where}: {missing[0]}: missing (a field of every {cls.__name__}"
                          + (f"; the file has {near[0]!r}" if near else "") + ")")
    if unknown:
        near = difflib.get_close_matches(unknown[0], names, n=1)
        raise RecordError(f"{where}: {unknown[0]}: unknown field of a {cls.__name__}"
                          + (f" (did you mean {near[0]!r}?)" if near else ""))
    hints = typing.get_type_hints(cls)
    return cls(**{n: _value(hints[n], data[n], f"{where}: {n}") if n in data else None
                  for n in names})


def _value(tp, v, where):
    """``v`` read as type ``tp`` (the field's annotation)."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if tp is typing.Any or tp is object:
        return v
    if dataclasses.is_dataclass(tp):
        return from_dict(tp, v, where)
    if origin in (typing.Union, types.UnionType):
        if v is None and type(None) in args:
            return None
        kinds = [a for a in args if a is not type(None)]
        if len(kinds) != 1:
            raise TypeError(f"{where}: a record field is one type or None, not {tp}")
        return _value(kinds[0], v, where)
    if tp in (tuple, list) or origin in (tuple, list):
        if not isinstance(v, (list, tuple)):
            raise RecordError(f"{where}: expected a list, got {v!r}")
        item = args[0] if args else typing.Any
        out = [_value(item, x, f"{where}[{k}]") for k, x in enumerate(v)]
        return tuple(out) if (tp is tuple or origin is tuple) else out
    if tp is dict or origin is dict:
        if not isinstance(v, dict):
            raise RecordError(f"{where}: expected an object, got {v!r}")
        item = args[1] if args else typing.Any
        return {k: _value(item, x, f"{where}.{k}") for k, x in v.items()}
    if tp is float:
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            return float(v)
        raise RecordError(f"{where}: expected a number, got {v!r}")
    if tp in (int, str, bool):
        if isinstance(v, tp) and not (tp is int and isinstance(v, bool)):
            return v
        raise RecordError(f"{where}: expected {'an' if tp is int else 'a'} "
                          f"{ {int: 'integer', str: 'string', bool: 'boolean'}[tp]}, got {v!r}")
    raise TypeError(f"{where}: no reader for a record field of type {tp}")


# ------------------------------------------------------------------------------ tables
def _columns(records) -> list:
    """The fields of the records' CSV: all, but an optional one that no record has."""
    cls = type(records[0])
    return [f for f in dataclasses.fields(cls)
            if not (f.metadata.get("optional") and all(getattr(r, f.name) is None
                                                       for r in records))]


def frame(records):
    """The records as a pandas DataFrame, one column per field (:func:`_columns`)."""
    import pandas as pd
    if not records:
        return pd.DataFrame()
    cols = _columns(records)
    return pd.DataFrame([{f.name: getattr(r, f.name) for f in cols} for r in records],
                        columns=[f.name for f in cols])


def write_csv(path: Path, records) -> None:
    with replacing(Path(path)) as tmp:
        frame(records).to_csv(tmp, index=False)


def read_csv(cls, path: Path) -> list:
    """The ``cls`` records of a CSV written by :func:`write_csv`: every column of a field
    present (an optional one may be absent), none unknown; RecordError in one line."""
    import pandas as pd
    path = Path(path)
    try:
        table = pd.read_csv(path, keep_default_na=False, dtype=str)
    except (OSError, ValueError) as e:
        raise RecordError(f"{path}: expected a CSV of {cls.__name__} records ({e})") from None
    fields = {f.name: f for f in dataclasses.fields(cls)}
    for name, f in fields.items():
        if name not in table.columns and not f.metadata.get("optional"):
            raise RecordError(f"{path}: {name}: missing column (a {cls.__name__} has "
                              f"{', '.join(fields)})")
    for name in table.columns:
        if name not in fields:
            raise RecordError(f"{path}: {name}: unknown column of a {cls.__name__}")
    hints = typing.get_type_hints(cls)
    out = []
    for k, row in enumerate(table.to_dict("records")):
        data = {n: _cell(hints[n], row.get(n, ""), f"{path}: row {k + 1}: {n}")
                for n in fields}
        out.append(from_dict(cls, data, f"{path}: row {k + 1}"))
    return out


def _cell(tp, text: str, where):
    """A CSV cell as the JSON value of a field of type ``tp``: "" is None (NaN for a float)."""
    kinds = [a for a in typing.get_args(tp) if a is not type(None)] or [tp]
    kind = kinds[0]
    if text == "":
        return math.nan if tp is float else None if kind is not str else ""
    try:
        return float(text) if kind is float else int(text) if kind is int else text
    except ValueError:
        raise RecordError(f"{where}: expected a number, got {text!r}") from None


def markdown_table(records) -> list:
    """The header, rule and rows of a markdown table of the fields with ``md`` metadata, in the
    order of their place (an optional field that no record has is left out)."""
    cols = sorted((f.metadata["md"] for f in _columns(records) if f.metadata.get("md")),
                  key=lambda m: m[0])
    return (["| " + " | ".join(m[1] for m in cols) + " |", "|" + "---|" * len(cols)]
            + ["| " + " | ".join(m[2](r) for m in cols) + " |" for r in records])
