"""Result files are written atomically: an error leaves no partial file."""
import pytest

from dem.fileio import atomic_path, write_csv


def test_error_leaves_no_file_and_keeps_the_old_one(tmp_path):
    target = tmp_path / "out.csv"
    write_csv(target, ["a"], [[1.0]])
    before = target.read_text()
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("boom")
    assert target.read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]


def test_csv_floats_round_trip(tmp_path):
    x = 0.1 + 0.2
    write_csv(tmp_path / "x.csv", ["x", "y"], [[x, None]])
    assert tmp_path.joinpath("x.csv").read_text().splitlines()[1] == f"{x!r},"


def test_result_files_get_the_umask_mode(tmp_path):
    import os
    umask = os.umask(0o022)
    try:
        write_csv(tmp_path / "m.csv", ["a"], [[1.0]])
    finally:
        os.umask(umask)
    assert (tmp_path / "m.csv").stat().st_mode & 0o777 == 0o644
