"""The accuracy bench: its cache of converted corrected logs (bench.accuracy.converted), its
cases side by side and at the phases of the matcher's blocks (bench.phase)."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from bench import accuracy, phase
from fastslam.geometry import wrap_angle
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


def test_seeds_are_numbers_and_ranges_in_the_order_given():
    assert accuracy.seed_list(["0-2", "7", "4-5"]) == [0, 1, 2, 7, 4, 5]
    assert accuracy.seed_list(["3-3"]) == [3]
    for bad in ("3-1", "x", "1-", "-2", "1-2-3"):
        with pytest.raises(ValueError, match="--seeds"):
            accuracy.seed_list([bad])


def test_cases_side_by_side_keep_their_order_results_and_own_cpu_time(tmp_path, monkeypatch):
    # two cases at once: each row's CPU is its own process's (the children's total mixed
    # them: the later of two cases took both), and the results are those of a case alone
    monkeypatch.setattr(accuracy, "CACHE", tmp_path / "cache")
    both = tmp_path / "both.json"
    assert accuracy.main(["--logs", "seattle", "--seeds", "0-1", "--jobs", "2", "--json", str(both)]) == 0
    rows = json.loads(both.read_text())
    assert [(r["log"], r["seed"]) for r in rows] == [("seattle", 0), ("seattle", 1)]
    for r in rows:
        assert 0.5 < r["cpu_s"] <= 1.2 * r["wall_s"], r
    alone = tmp_path / "alone.json"
    assert accuracy.main(["--logs", "seattle", "--seeds", "1", "--json", str(alone)]) == 0
    assert json.loads(alone.read_text())[0]["error"] == rows[1]["error"]


def test_a_failing_case_is_one_line_and_exit_1_and_starts_no_other(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(accuracy, "CACHE", tmp_path / "cache")
    started = []
    real_case = accuracy.corrected_case

    def counted(*args, **kw):
        started.append(args[1])
        return real_case(*args, **kw)

    monkeypatch.setattr(accuracy, "corrected_case", counted)
    code = accuracy.main(["--logs", "seattle", "--seeds", "0-5", "--set", "particles=0"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1
    assert len(err) == 1 and err[0].startswith("bench.accuracy: ") and "particles" in err[0], err
    assert started == [0]


def test_phases_are_0_to_3_and_a_phase_beyond_is_refused_before_any_case(capsys):
    assert accuracy.seed_list(["0-3"], "phase", "--phases") == [0, 1, 2, 3]
    with pytest.raises(SystemExit) as stop:
        accuracy.main(["--logs", "seattle", "--seeds", "0", "--phases", "2", "4"])
    assert stop.value.code == 2 and "--phases: 4 is not a phase" in capsys.readouterr().err
    assert phase.main(["7", "any.bag", "--out", "x"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["bench.phase: the first argument is the phase, 0 to 3; got '7'"]


def test_each_phase_is_a_case_of_its_own_and_phase_0_is_the_offline_tool_itself(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(accuracy, "CACHE", tmp_path / "cache")
    both = tmp_path / "both.json"
    assert accuracy.main(["--logs", "seattle", "--seeds", "0", "--phases", "0-1", "1", "--json", str(both)]) == 0
    out = capsys.readouterr().out
    assert "seattle p0 " in out and "seattle p1 " in out                    # a table line per phase
    rows = json.loads(both.read_text())
    assert [(r["log"], r["seed"], r["phase"]) for r in rows] == [("seattle", 0, 0), ("seattle", 0, 1)]   # 1 once
    plain = tmp_path / "plain.json"
    assert accuracy.main(["--logs", "seattle", "--seeds", "0", "--json", str(plain)]) == 0
    assert json.loads(plain.read_text())[0]["error"] == rows[0]["error"]   # phase 0: the same run to the bit
    assert rows[1]["error"] != rows[0]["error"]                             # the blocks moved: another run


def test_odometry_noise_0_feeds_the_log_s_own_poses_and_leaves_the_scans_cost(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(accuracy, "CACHE", tmp_path / "cache")
    runs = {}
    for level in ("0", "1"):
        out = tmp_path / f"noise{level}.json"
        assert accuracy.main(["--logs", "seattle", "--seeds", "0", "--odom-noise", level, "--json", str(out)]) == 0
        runs[level] = json.loads(out.read_text())[0]
    assert "odometry noise 0," in capsys.readouterr().out       # the header says which
    bag = accuracy.converted("seattle", 0, 0.0)
    assert "-noise0-" in bag.name
    _, odom = read_trajectory(bag.with_name(bag.name + ".odom.txt"))
    _, truth = read_trajectory(bag.with_name(bag.name + ".gt.txt"))
    assert abs(odom[:, :2] - truth[:, :2]).max() < 1e-9         # the odometry is the log's poses
    assert abs(wrap_angle(odom[:, 2] - truth[:, 2])).max() < 1e-9
    # seattle, seed 0: 0.049 m with the log's poses as odometry, 0.094 m with the noise
    assert runs["0"]["error"] < 0.75 * runs["1"]["error"], runs


def test_a_negative_odometry_noise_is_refused_before_any_case(capsys):
    with pytest.raises(SystemExit) as stop:
        accuracy.main(["--logs", "seattle", "--seeds", "0", "--odom-noise", "-1"])
    assert stop.value.code == 2 and "--odom-noise: -1 is not a noise level" in capsys.readouterr().err
