"""python -m fastslam.carmen_to_bag: times made increasing, the reference trajectory's
name, the log's poses, and errors as one line and an exit code (bags: test/integration)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fastslam import carmen_to_bag
from fastslam.carmen_to_bag import convert, increasing_times, log_trajectory, reference_path
from fastslam.io.carmen_log import read_log

# two FLASER scans of 3 beams whose logger times step back (2.0 then 1.5)
LOG = """\
FLASER 3 1.0 2.0 3.0 0.1 0.2 0.3 1.0 2.0 0.5 9.0 host 2.0
FLASER 3 1.5 2.5 3.5 0.4 0.5 0.6 1.5 2.5 0.7 9.5 host 1.5
"""


def test_times_are_made_strictly_increasing():
    t = increasing_times(np.array([1.0, 2.0, 1.5, 1.9, 3.0, 3.0]), min_dt=0.01)
    np.testing.assert_allclose(t, [1.0, 2.0, 2.01, 2.02, 3.0, 3.01])


def test_equal_times_are_spread_by_min_dt():
    np.testing.assert_allclose(increasing_times(np.array([5.0, 5.0, 5.0]), min_dt=0.5), [5.0, 5.5, 6.0])
    np.testing.assert_array_equal(increasing_times(np.array([1.0, 2.0])), [1.0, 2.0])   # already increasing


def test_reference_paths_sit_beside_the_bag():
    assert reference_path("out/intel.bag") == Path("out/intel.bag.gt.txt")
    assert reference_path(Path("out/intel.bag"), "odom") == Path("out/intel.bag.odom.txt")


def test_log_trajectory_is_the_robot_poses_at_increasing_times(tmp_path):
    (tmp_path / "a.log").write_text(LOG)
    times, poses = log_trajectory(read_log(tmp_path / "a.log"))
    np.testing.assert_allclose(times, [2.0, 2.001])              # 1.5 came after 2.0 in the file
    np.testing.assert_array_equal(poses, [[1.0, 2.0, 0.5], [1.5, 2.5, 0.7]])


def test_a_log_without_timestamps_gets_a_scan_a_second_and_a_warning(tmp_path, capsys):
    # orebro's FLASER lines all end "0 pippo 0": no scan may be stamped 0 (ROS: unstamped)
    untimed = "".join(f"FLASER 3 1.0 2.0 3.0 {x} 0.0 0.0 {x} 0.0 0.0 0 pippo 0\n" for x in (0.0, 1.0, 3.0))
    (tmp_path / "u.log").write_text(untimed)
    times, _ = log_trajectory(read_log(tmp_path / "u.log"))
    np.testing.assert_array_equal(times, [1.0, 2.0, 3.0])
    assert carmen_to_bag.main([str(tmp_path / "u.log"), "--out", str(tmp_path / "u.bag"), "--quiet"]) == 0
    captured = capsys.readouterr()
    assert "no timestamps (all 0 s): stamped 1 s apart" in captured.err
    assert "3 scans over 2.0 s" in captured.out


def test_a_saturating_laser_is_named_and_its_limit_written_as_range_max(tmp_path, capsys):
    from fastslam.io.bag_reader import read_bag

    rows = np.random.default_rng(0).uniform(0.5, 20.0, (30, 180))
    rows[:, :10] = 51.15                      # 300 of 5400 readings at the laser's limit
    lines = [f"FLASER 180 {' '.join(f'{v:.2f}' for v in r)} {0.1 * k} 0 0 {0.1 * k} 0 0 {k}.0 host {k}.0"
             for k, r in enumerate(rows, start=1)]
    (tmp_path / "s.log").write_text("\n".join(lines) + "\n")
    assert carmen_to_bag.main([str(tmp_path / "s.log"), "--out", str(tmp_path / "s.bag"), "--quiet"]) == 0
    assert "the laser saturates at 51.0 m" in capsys.readouterr().err
    bag = read_bag(tmp_path / "s.bag")
    assert bag.scans[0].range_max == pytest.approx(51.0)
    assert np.isinf(bag.scans[0].ranges[:10]).all() and np.isfinite(bag.scans[0].ranges[10:]).all()


def test_a_log_without_scans_writes_nothing(tmp_path):
    (tmp_path / "odom.log").write_text("ODOM 1.0 2.0 0.5 0.3 0.1 0.0 300.0 host 300.5\n")
    with pytest.raises(ValueError, match="no FLASER or ROBOTLASER1 scans"):
        convert(read_log(tmp_path / "odom.log"), tmp_path / "x.bag")
    assert list(tmp_path.iterdir()) == [tmp_path / "odom.log"]


def test_cli_errors_are_one_line_and_exit_1(tmp_path, capsys):
    assert carmen_to_bag.main([str(tmp_path / "missing.log"), "--out", str(tmp_path / "x.bag")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and "missing.log" in err
    (tmp_path / "a.log").write_text(LOG)
    (tmp_path / "old.bag").write_bytes(b"old")
    assert carmen_to_bag.main([str(tmp_path / "a.log"), "--out", str(tmp_path / "old.bag")]) == 1
    assert "exists" in capsys.readouterr().err
    assert (tmp_path / "old.bag").read_bytes() == b"old"
    assert not reference_path(tmp_path / "old.bag").exists()
