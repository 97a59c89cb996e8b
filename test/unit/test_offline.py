"""python -m fastslam.offline without a bag file: the replay loop on hand-made records (drops
counted by kind), the files it writes, and errors as one line and exit code 2 (bags:
test/integration/test_offline.py)."""
from __future__ import annotations

import json

import numpy as np
import yaml

from fastslam import offline
from fastslam.config import SlamConfig
from fastslam.io.bag_reader import BagData
from fastslam.io.map_files import load_map
from fastslam.io.records import OdomRecord, ScanRecord
from fastslam.io.trajectory_files import read_trajectory
from fastslam.transforms import LaserMount

ANGLES = np.radians(np.arange(0.0, 360.0, 2.0))


def records(room_ranges) -> BagData:
    """Odometry at 1.0, 1.2, 1.4 s along +x; scans of the pillar room: one before any
    odometry, two good ones, one without beams, one long after the odometry ended."""
    odoms = [OdomRecord(1.0 + 0.2 * k, 0.05 * k, 0.0, 0.0) for k in range(3)]
    def scan(t: float, x: float) -> ScanRecord:
        return ScanRecord(t, room_ranges([x, 0.0, 0.0], ANGLES).astype(np.float32), 0.0, float(ANGLES[1]),
                          0.12, 3.5)
    empty = ScanRecord(1.3, np.zeros(0, np.float32), 0.0, 0.1, 0.12, 3.5)
    scans = [scan(0.5, 0.0), scan(1.0, 0.0), scan(1.2, 0.05), empty, scan(5.0, 0.1)]
    return BagData(scans=scans, odoms=odoms, mount=LaserMount(), scan_topic="/scan", odom_topic="/odom")


def test_run_bag_counts_updates_and_drops_by_kind(room_ranges):
    result = offline.run_bag(records(room_ranges), SlamConfig(particles=3, seed=0))
    assert (result.scans, result.updates, len(result.update_ms)) == (5, 2, 2)
    assert result.dropped == {"no odometry received yet": 1, "empty scan": 1,
                              "no odometry at the scan's time": 1}
    np.testing.assert_allclose(result.slam.trajectory()[:, :2], [[1.0, 0.0], [1.2, 0.05]], atol=0.02)
    stats = result.stats()
    assert stats["scans"] == 5 and stats["updates"] == 2 and stats["dropped"] == result.dropped
    assert stats["ms_per_update_median"] > 0 and stats["events"] == [] and stats["odometry_stalls_tracked"] == 0 \
        and stats["matches_beyond_gate"] == 0 and stats["match_loops"] == 0


def test_write_results(tmp_path, room_ranges):
    cfg = SlamConfig(particles=3, seed=0)
    result = offline.run_bag(records(room_ranges), cfg)
    out = tmp_path / "out"
    out.mkdir()                       # main() hands it a folder it made (staged_folder)
    offline.write_results(out, result, cfg)
    assert sorted(p.name for p in out.iterdir()) == ["config.yaml", "live_poses.txt", "map.pgm", "map.png",
                                                    "map.yaml", "stats.json", "trajectory.txt",
                                                    "trajectory_scans.txt", "trajectory_smoothed.txt"]
    t, poses = read_trajectory(out / "trajectory.txt")
    np.testing.assert_array_equal(np.c_[t, poses], result.slam.trajectory())
    # the two scans the filter saw were both processed: every-scan files are the trajectory itself
    for name in ("trajectory_scans.txt", "trajectory_smoothed.txt", "live_poses.txt"):
        t, poses = read_trajectory(out / name)
        np.testing.assert_array_equal(np.c_[t, poses], result.slam.trajectory())
    occ, res, origin = load_map(out / "map.yaml")
    assert occ.shape == result.slam.grid.shape and res == 0.05
    assert origin == (float(result.slam.grid.origin[0]), float(result.slam.grid.origin[1]), 0.0)
    assert np.count_nonzero(occ == 100) > 50                    # the walls of the room
    assert json.loads((out / "stats.json").read_text())["updates"] == 2
    assert SlamConfig.from_dict(yaml.safe_load((out / "config.yaml").read_text())) == cfg


def test_cli_reports_a_bad_parameter_and_a_missing_bag(tmp_path, capsys):
    assert offline.main([str(tmp_path / "none.bag"), "--out", str(tmp_path)]) == 2
    assert "no bag at" in capsys.readouterr().err
    assert offline.main([str(tmp_path / "none.bag"), "--out", str(tmp_path), "--set", "particles=0"]) == 2
    assert "particles=0 must be in" in capsys.readouterr().err


def test_cli_reports_a_bad_override_and_a_missing_config(tmp_path, capsys):
    assert offline.main(["x.bag", "--out", str(tmp_path), "--set", "particles"]) == 2
    assert capsys.readouterr().err == "error: override 'particles' must look like key=value\n"
    assert offline.main(["x.bag", "--out", str(tmp_path), "--config", str(tmp_path / "nope.yaml")]) == 2
    assert "nope.yaml" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []                        # nothing half-written
