"""Writing TOML documents (the standard library only reads TOML).

Enough for parameter files with their provenance: tables nested in tables, scalars
(str, bool, int, float including inf and nan), and arrays of scalars. Keys that are not
bare (letters, digits, ``_``, ``-``) are quoted; ``None`` values are left out (TOML has no
null). :func:`dumps` output reads back with :mod:`tomllib` to the same document.
"""
from __future__ import annotations

import json
import math
import re
from typing import Mapping

_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def _key(k: str) -> str:
    return k if _BARE.match(k) else json.dumps(k)


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(float(v))          # numpy floats repr as np.float64(..)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v if x is not None) + "]"
    if hasattr(v, "item"):                 # numpy scalars
        return _value(v.item())
    raise TypeError(f"cannot write {type(v).__name__} {v!r} as a TOML value")


def dumps(doc: Mapping, header: str = "") -> str:
    """The TOML text of ``doc``; ``header`` lines are written first as comments."""
    lines = [f"# {line}".rstrip() for line in header.splitlines()] if header else []
    _table(doc, (), lines)
    return "\n".join(lines).lstrip("\n") + "\n"


def _table(doc: Mapping, prefix: tuple[str, ...], lines: list[str]) -> None:
    scalars = {k: v for k, v in doc.items() if not isinstance(v, Mapping) and v is not None}
    tables = {k: v for k, v in doc.items() if isinstance(v, Mapping)}
    if prefix and (scalars or not tables):
        lines.append("")
        lines.append("[" + ".".join(_key(k) for k in prefix) + "]")
    for k, v in scalars.items():
        lines.append(f"{_key(str(k))} = {_value(v)}")
    for k, v in tables.items():
        _table(v, prefix + (str(k),), lines)
