"""Output safety (issue 13): file modes follow the umask, orphan temporaries are removed, a result
folder lands whole or not at all, JSON is strict, output paths are probed before work."""

import json
import os

import numpy as np
import pytest

from platcal.errors import InputError
from platcal.io import atomic_files, atomic_write_text, check_writable, json_safe, json_text


@pytest.fixture()
def umask_027():
    old = os.umask(0o027)
    yield
    os.umask(old)


def test_atomic_write_follows_umask(tmp_path, umask_027):
    atomic_write_text(tmp_path / "a.txt", "x")
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o640
    with atomic_files(tmp_path / "res") as tmp:
        tmp("b.csv").write_text("y")
    assert (tmp_path / "res" / "b.csv").stat().st_mode & 0o777 == 0o640


def test_rerun_removes_orphan_temporaries_of_its_target_only(tmp_path):
    orphan = tmp_path / ".summary.json.abc123.part"  # left by a killed writer of summary.json
    other = tmp_path / ".estimates.csv.xyz.part"  # another target's: not this writer's business
    orphan.write_text("half")
    other.write_text("half")
    atomic_write_text(tmp_path / "summary.json", "{}")
    assert not orphan.exists() and other.exists()
    with atomic_files(tmp_path) as tmp:
        tmp("estimates.csv").write_text("a")
    assert not other.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["estimates.csv", "summary.json"]


def test_result_folder_lands_whole_or_not_at_all(tmp_path):
    out = tmp_path / "res"
    out.mkdir()
    (out / "keep.txt").write_text("a user's file")
    (out / "estimates.csv").write_text("old")
    with pytest.raises(OSError):
        with atomic_files(out) as tmp:
            tmp("estimates.csv").write_text("new")
            tmp("summary.json").write_text("{}")
            raise OSError(28, "No space left on device")  # as a full disk would, mid-way
    # nothing renamed, no temporaries left, the old result and the user's file untouched
    assert sorted(p.name for p in out.iterdir()) == ["estimates.csv", "keep.txt"]
    assert (out / "estimates.csv").read_text() == "old"
    with atomic_files(out) as tmp:
        tmp("estimates.csv").write_text("new")
        tmp("summary.json").write_text("{}")
    assert sorted(p.name for p in out.iterdir()) == ["estimates.csv", "keep.txt", "summary.json"]
    assert (out / "estimates.csv").read_text() == "new"


def test_json_is_strict_and_plain():
    obj = {"a": np.int64(7), "b": float("nan"), "c": [np.float64(1.5), -np.inf], "d": np.array([1, 2])}
    assert json_safe(obj) == {"a": 7, "b": None, "c": [1.5, None], "d": [1, 2]}
    text = json_text(obj)
    assert "NaN" not in text and "Infinity" not in text
    assert json.loads(text)["a"] == 7


@pytest.mark.parametrize("kind", ["parent is a file", "file is a folder", "folder is a file"])
def test_check_writable_refuses(kind, tmp_path):
    (tmp_path / "f").write_text("x")
    (tmp_path / "d").mkdir()
    path, folder = {"parent is a file": (tmp_path / "f" / "a" / "b.csv", False),
                    "file is a folder": (tmp_path / "d", False),
                    "folder is a file": (tmp_path / "f", True)}[kind]
    before = sorted(os.listdir(tmp_path))
    with pytest.raises(InputError) as e:
        check_writable(path, "--out", folder=folder)
    assert e.value.field == "--out"
    assert sorted(os.listdir(tmp_path)) == before


def test_check_writable_accepts_new_nested_folder_and_leaves_nothing(tmp_path):
    check_writable(tmp_path / "a" / "b" / "c", "--out", folder=True)
    check_writable(tmp_path / "x.csv", "--out")
    assert list(tmp_path.iterdir()) == []
