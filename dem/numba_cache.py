"""Point numba's on-disk cache at a directory keyed on the kernels' sources.

numba's ``cache=True`` keys a cached kernel on its *own* file only: editing a
callee in another module leaves callers' caches stale (seen on this machine class: a
stale tier-2 kernel looped forever after a callee in another module changed). contfab
kernels call :mod:`dem.conventions` and read constants of other modules, so a per-file
key is not enough. Before numba is imported we set ``NUMBA_CACHE_DIR`` to
``~/.cache/contfab/numba/<kernel digest>``, a hash of :func:`kernel_sources`: every
module of ``dem/`` and ``contfab/`` that compiles a numba function, and every project
module those import, transitively. A compiled function can reach only the names of its
own module, and those come from its own source or from a module it imports, so the
import closure holds every callee and every global constant a kernel can read: an edit
of any of them gives a fresh cache. An edit elsewhere (the CLI, the FEM drivers, the
scenes, the docs) keeps the warm one.

A user who sets ``NUMBA_CACHE_DIR`` keeps it (and owns its staleness). If numba was
imported first (a test's ``import numba`` before ``import dem``), numba has already read
its environment, so the directory is also set on ``numba.config.CACHE_DIR``, which the
cache locator reads when each ``cache=True`` kernel is decorated; otherwise those kernels
would fall back to ``__pycache__`` with per-file keys.
"""
from __future__ import annotations

import hashlib
import inspect
import os
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
"""The directory holding the ``dem`` and ``contfab`` packages."""
PACKAGES = ("dem", "contfab")
_COMPILES = re.compile(r"jit\(|@(?:numba\.)?(?:njit|jit|vectorize|guvectorize|cfunc|stencil)\b")
"""A numba decorator or a call of njit/jit: the module compiles a numba function."""


def source_digest(packages: tuple[str, ...] = PACKAGES, root: Path = ROOT) -> str:
    """SHA-1 over the relative path and bytes of every .py file of ``packages`` (both by
    default; ``("dem",)`` keys results that depend on the DEM's code only)."""
    return _digest(sorted(f for pkg in packages for f in (root / pkg).rglob("*.py")), root)


def kernel_digest(root: Path = ROOT) -> str:
    """SHA-1 over the relative path and bytes of :func:`kernel_sources` (the cache key)."""
    return _digest(kernel_sources(root), root)


def _digest(files, root: Path) -> str:
    h = hashlib.sha1()
    for f in files:
        h.update(str(f.relative_to(root)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


def kernel_sources(root: Path = ROOT) -> list[Path]:
    """The modules of ``dem/`` and ``contfab/`` that compile numba functions, and every
    project module they import, transitively (sorted paths)."""
    modules = {_module_name(f, root): f for pkg in PACKAGES for f in (root / pkg).rglob("*.py")}
    todo = [name for name, f in modules.items() if _COMPILES.search(f.read_text())]
    seen: set[str] = set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        todo.extend(_imports(name, modules))
    return sorted(modules[name] for name in seen)


def _module_name(file: Path, root: Path) -> str:
    parts = file.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


_IMPORT = re.compile(r"^(?:from[ \t]+(\.*[\w.]*)[ \t]+import[ \t]+(\([^)]*\)|[^\n]*)"
                     r"|import[ \t]+([^\n]*))", re.MULTILINE)
"""A module-level import statement (at the start of a line): the globals a compiled
function can see come only from those."""


def _imports(name: str, modules: dict[str, Path]) -> set[str]:
    """The project modules ``name`` imports at module level (with the packages they sit
    in: importing ``a.b.c`` runs ``a/__init__`` and ``a/b/__init__``)."""
    file = modules[name]
    package = name if file.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for base, names, plain in _IMPORT.findall(file.read_text()):
        if plain:
            targets = [t.split()[0] for t in plain.split("#")[0].split(",") if t.strip()]
        else:
            dots = len(base) - len(base.lstrip("."))
            if dots:
                up = package.split(".")[:len(package.split(".")) - dots + 1]
                base = ".".join(up + ([base.lstrip(".")] if base.lstrip(".") else []))
            listed = re.sub(r"#[^\n]*", "", names).strip("()")
            targets = [base] + [f"{base}.{t.split()[0]}" for t in listed.split(",") if t.strip()]
        for t in targets:
            parts = t.split(".")
            found.update(m for m in (".".join(parts[:k]) for k in range(1, len(parts) + 1))
                         if m in modules)
    return found


def configure() -> None:
    """Set NUMBA_CACHE_DIR (and numba's config if numba is loaded) unless the user set it."""
    if "NUMBA_CACHE_DIR" in os.environ:
        return
    base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
    os.environ["NUMBA_CACHE_DIR"] = str(base / "contfab" / "numba" / kernel_digest())
    if "numba" in sys.modules:
        sys.modules["numba"].config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]


def is_compiled(dispatcher) -> bool:
    """True if the ``cache=True`` numba function ``dispatcher`` needs no compiling: it is
    compiled in this process, or numba's on-disk cache holds an entry for it (its index
    file ``<module>.<name>-<line>.py<version>.nbi``, in the cache directory's folder for
    the source's directory, or in ``__pycache__`` beside the source if no directory is set)."""
    if dispatcher.signatures:
        return True
    source = Path(inspect.getfile(dispatcher.py_func)).resolve()
    index = f"{source.stem}.{dispatcher.py_func.__qualname__}-*.nbi"
    cache_dir = sys.modules["numba"].config.CACHE_DIR if "numba" in sys.modules else ""
    folder = (Path(cache_dir).glob(f"{source.parent.name}_*") if cache_dir
              else [source.parent / "__pycache__"])
    return any(any(f.glob(index)) for f in folder)


_ANNOUNCED: set = set()


def announce_compiling(dispatcher, what: str, minutes: str, stream=None) -> bool:
    """Say once per process, on ``stream`` (stderr), that ``what`` is being compiled when
    ``dispatcher`` is not compiled yet (:func:`is_compiled`): the first use after an
    install or a source edit waits ``minutes`` for numba, later runs load the cache.
    Returns whether it said so."""
    if dispatcher in _ANNOUNCED or is_compiled(dispatcher):
        return False
    _ANNOUNCED.add(dispatcher)
    print(f"compiling {what} (first use of this code; about {minutes} on one core, "
          f"cached for later runs)", file=sys.stderr if stream is None else stream, flush=True)
    return True
