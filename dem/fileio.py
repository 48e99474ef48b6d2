"""Writing result files so that none is ever left half-written.

Every writer in the project goes through :func:`atomic_path`: it hands out a
temporary name in the destination directory and renames it onto the final name
only when the block finishes without an exception (rename is atomic on POSIX
within one file system). On error the temporary file is removed and the old
file, if any, is untouched.
"""
from __future__ import annotations

import contextlib
import csv
import json
import os
import tempfile
from pathlib import Path
from typing import Iterator, Mapping, Sequence


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` on success.

    The suffix of ``path`` is kept on the temporary name, so writers that pick a
    format from the extension (matplotlib, meshio) still work.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.tmp-", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600; result files get the usual mode
    tmp = Path(tmp)
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_csv(path: str | os.PathLike, columns: Sequence[str], rows: Sequence[Sequence]) -> Path:
    """Write a CSV with a header row, atomically. Floats use repr (round-trip exact)."""
    with atomic_path(path) as tmp:
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(columns)
            for row in rows:
                w.writerow(["" if v is None else (repr(float(v)) if isinstance(v, float) else v)
                            for v in row])
    return Path(path)


def write_json(path: str | os.PathLike, data: Mapping) -> Path:
    """Write a JSON document (indented, keys in insertion order), atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(data, indent=2, default=_jsonable) + "\n")
    return Path(path)


def _jsonable(obj):
    """numpy scalars and arrays, and Paths, as plain JSON values."""
    if hasattr(obj, "tolist"):
        return obj.tolist()
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    raise TypeError(f"not JSON serializable: {type(obj).__name__}")
