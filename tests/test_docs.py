"""The repository explains itself: no process narration, no pointer outside it, no dead link.

* No file of README.md, docs/, contfab/, dem/ or cases/ (source, markdown and data text)
  says how the work was done or points at a design file outside the repository.
* Every markdown link and image of README.md, CHANGELOG.md and docs/**/*.md resolves to a
  file of the repository, and so does every repository path they quote in backticks
  (``docs/...``, ``contfab/...``, ...), placeholders such as ``cases/NAME.py`` aside.

Each checker is also run on a planted violation, so a checker that cannot fire fails.
"""
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCANNED = ("README.md", "docs", "contfab", "dem", "cases")
TEXT_SUFFIXES = {".py", ".md", ".toml", ".json", ".txt", ".cfg"}
NARRATION = re.compile(
    r"stop [0-9]+|session [0-9]+|branch `|/work/|\.\./shared|the lead\b|the helper|DESIGN"
    r"|\bissue [0-9]+|this round|the `search` tool",
    re.IGNORECASE)
"""Process words, machine paths and pointers to the design file (case-insensitive)."""
MARKDOWN_LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
CODE_SPAN = re.compile(r"`([^`\n]+)`")
REPO_PATH = re.compile(r"^(?:docs|contfab|dem|cases|tests)/[\w./-]*\.\w+$")
PLACEHOLDER = re.compile(r"(?:^|/)[A-Z][A-Z_]+(?:\.\w+)?$|[*<>{}]")


def scanned_files() -> list[Path]:
    files = []
    for name in SCANNED:
        path = ROOT / name
        if path.is_file():
            files.append(path)
        else:
            files += [p for p in sorted(path.rglob("*"))
                      if p.is_file() and p.suffix in TEXT_SUFFIXES and "__pycache__" not in p.parts]
    return files


def markdown_files() -> list[Path]:
    return [ROOT / "README.md", ROOT / "CHANGELOG.md", *sorted((ROOT / "docs").rglob("*.md"))]


def narration(text: str) -> list[str]:
    """The lines of ``text`` that narrate the work or point outside the repository."""
    return [line.strip() for line in text.splitlines() if NARRATION.search(line)]


def dead_links(text: str, where: Path) -> list[str]:
    """Relative links and quoted repository paths of a markdown file that do not resolve to a
    file of the repository (links relative to the file, quoted paths to the root)."""
    bad = []
    for target in MARKDOWN_LINK.findall(text):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
            continue                                    # a URL or an anchor in the same file
        path = (where.parent / target.split("#")[0]).resolve()
        if ROOT not in path.parents or not path.exists():
            bad.append(target)
    for span in CODE_SPAN.findall(text):
        for token in span.split():
            token = token.strip("(),;:'\"").split("::")[0]
            if token.startswith("../"):
                bad.append(token)                       # a path out of the repository
            elif REPO_PATH.match(token) and not PLACEHOLDER.search(token) \
                    and not (ROOT / token).exists():
                bad.append(token)
    return bad


def test_no_process_narration_or_outside_pointer_in_the_product():
    found = {str(p.relative_to(ROOT)): lines for p in scanned_files()
             if (lines := narration(p.read_text(encoding="utf-8", errors="replace")))}
    assert not found, found


def test_markdown_links_and_quoted_paths_resolve_inside_the_repository():
    found = {str(p.relative_to(ROOT)): bad for p in markdown_files()
             if (bad := dead_links(p.read_text(encoding="utf-8"), p))}
    assert not found, found


@pytest.mark.parametrize("line", [
    "Measured at stop 12 on main.", "as in session 11", "the DEM helper, branch `dem-e`",
    "see /work/notes/s12/run.py", "Design notes are in ../shared/DESIGN.md",
    "(DESIGN §4)", "asked by the lead", "the acceptance points of issue 3",
    "not measured this round", "the `search` tool found it"])
def test_the_narration_check_fires_on_each_pattern(line):
    assert narration(f"A sentence.\n{line}\nAnother.") == [line]


def test_the_narration_check_passes_product_text():
    assert narration("Stop conditions of a stage; the branch vector l = xj - xi; "
                     "tension positive (docs/theory.md §1).") == []


def test_the_link_check_fires_on_dead_and_outside_links():
    where = ROOT / "docs" / "example.md"
    text = ("![plot](calibration/probing.png) [theory](theory.md#3) [web](https://example.org) "
            "[gone](missing.md) [out](../../outside.md) `docs/nowhere.md` `../shared/x.md` "
            "`contfab/params.py` `cases/NAME.py` `tests/test_cone.py::test_x`")
    assert dead_links(text, where) == ["missing.md", "../../outside.md", "docs/nowhere.md",
                                       "../shared/x.md"]
