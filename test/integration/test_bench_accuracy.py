"""The accuracy bench's cache of converted corrected logs (bench.accuracy.converted)."""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from bench import accuracy
from fastslam.io.trajectory_files import read_trajectory


@pytest.fixture(autouse=True)
def seattle_log(dev_data):
    dev_data("seattle-corrected.log.gz")


def test_a_new_conversion_removes_the_same_case_made_by_an_older_converter(tmp_path, monkeypatch):
    monkeypatch.setattr(accuracy, "CACHE", tmp_path)
    stale = [tmp_path / f"seattle-noise1-seed0-0123456789.bag{ext}" for ext in ("", ".gt.txt", ".odom.txt")]
    other_seed = tmp_path / "seattle-noise1-seed1-0123456789.bag"
    other_log = tmp_path / "intel-noise1-seed0-0123456789.bag"
    for f in stale + [other_seed, other_log]:
        f.write_text("old")
    bag = accuracy.converted("seattle", 0)
    assert bag.exists() and bag.with_name(bag.name + ".gt.txt").exists()
    assert not any(f.exists() for f in stale)
    assert other_seed.exists() and other_log.exists()          # other cases stay
    made = bag.stat().st_mtime_ns
    assert accuracy.converted("seattle", 0) == bag and bag.stat().st_mtime_ns == made   # reused, not made again


def test_another_bench_converting_the_same_case_at_the_same_time_is_no_failure(tmp_path, monkeypatch):
    # two benches side by side (one a core) convert the same new case: the other's whole
    # conversion lands in the cache while this one's converter runs
    monkeypatch.setattr(accuracy, "CACHE", tmp_path)
    run = subprocess.run

    def other_bench_lands_first(cmd, **kw):
        at = cmd.index("--out") + 1
        theirs = list(cmd)
        theirs[at] = str(tmp_path / Path(cmd[at]).name)
        assert run(theirs, **kw).returncode == 0
        return run(cmd, **kw)

    monkeypatch.setattr(accuracy.subprocess, "run", other_bench_lands_first)
    bag = accuracy.converted("seattle", 0)
    gt = bag.with_name(bag.name + ".gt.txt")
    assert bag.exists() and gt.exists()
    assert len(read_trajectory(gt)[0]) == 241                  # every scan of the log has its pose
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([bag.name, gt.name, bag.name + ".odom.txt"])
