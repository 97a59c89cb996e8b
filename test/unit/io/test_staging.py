"""Staged outputs: written under temporary names, renamed into place only when complete."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from fastslam.io.staging import partial_path, remove_stale, staged


def test_partial_names_are_hidden_and_carry_the_pid(tmp_path):
    assert partial_path(tmp_path / "out.bag") == tmp_path / f".out.bag.partial-{os.getpid()}"


def test_a_finished_block_renames_every_file(tmp_path):
    finals = [tmp_path / "a.txt", tmp_path / "b.bag"]
    (tmp_path / "a.txt").write_text("old")
    with staged(*finals) as temps:
        assert temps == [partial_path(f) for f in finals]
        for temp, text in zip(temps, ("new a", "new b")):
            temp.write_text(text)
        assert (tmp_path / "a.txt").read_text() == "old"       # nothing moves before the end
    assert [f.read_text() for f in finals] == ["new a", "new b"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.bag"]


def test_a_failing_block_leaves_the_old_files_and_no_temporaries(tmp_path):
    (tmp_path / "a.txt").write_text("old")
    with pytest.raises(OSError, match="disk full"):
        with staged(tmp_path / "a.txt", tmp_path / "b.txt") as temps:
            temps[0].write_text("half")
            raise OSError("disk full")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]
    assert (tmp_path / "a.txt").read_text() == "old"


def test_remove_stale_removes_only_what_dead_processes_left(tmp_path):
    done = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead = int(done.stdout)                                    # exited: its pid names no process now
    names = {f".m.pgm.partial-{dead}": True, f".m.yaml.partial-{dead}": True,
             f".m.pgm.partial-{os.getpid()}": False,           # this process's own: in use
             f".m.pgm.partial-{os.getppid()}": False,          # a living process's
             ".m.pgm.partial-abc": False,                      # not a pid
             f".other.pgm.partial-{dead}": False,              # another stem
             "m.pgm": False}
    for name in names:
        (tmp_path / name).write_text("x")
    removed = remove_stale(tmp_path, "m")
    assert sorted(p.name for p in removed) == sorted(n for n, gone in names.items() if gone)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(n for n, gone in names.items() if not gone)
