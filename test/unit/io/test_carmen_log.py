"""CARMEN log parsing on a hand-written snippet (plain and gzip)."""
from __future__ import annotations

import gzip
import math

import numpy as np
import pytest

from fastslam.io.carmen_log import CarmenError, flaser_geometry, read_log

SNIPPET = """\
# message formats defined: PARAM SYNC ODOM FLASER RLASER TRUEPOS
PARAM robot_frontlaser_offset 0.25 nohost 0
ODOM 1.0 2.0 0.5 0.3 0.1 0.0 300.0 host 300.5
FLASER 4 1.0 2.0 81.83 3.5 0.1 0.2 0.3 0.4 0.5 0.6 100.25 host 100.5
NEFF 15
ROBOTLASER1 0 -1.5 3.0 0.5 20.0 0.01 0 3 1.0 20.0 2.5 2 0.7 0.8 1.0 2.5 1.5707963267948966 1.0 2.0 1.5707963267948966 0.3 0.1 0.5 0.4 0.0 200.0 host 200.25
TRUEPOS 1 2 3 4 5 6 7 host 8

"""


@pytest.fixture(params=["plain", "gzip"])
def log_path(tmp_path, request):
    if request.param == "plain":
        path = tmp_path / "snippet.log"
        path.write_text(SNIPPET)
    else:
        path = tmp_path / "snippet.clf"          # gzip is detected by content, not by name
        path.write_bytes(gzip.compress(SNIPPET.encode()))
    return path


def test_flaser_fields(log_path):
    log = read_log(log_path)
    s = log.scans[0]
    assert s.kind == "FLASER" and s.t == 100.5 and s.ipc_t == 100.25
    np.testing.assert_array_equal(s.ranges, np.array([1.0, 2.0, np.inf, 3.5], np.float32))
    assert s.ranges.dtype == np.float32
    # 4 beams over 180 degrees: -90, -45, 0, 45 degrees
    assert s.angle_min == -math.pi / 2 and s.angle_increment == pytest.approx(math.pi / 4)
    np.testing.assert_array_equal(s.laser_pose, [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(s.robot_pose, [0.4, 0.5, 0.6])
    assert s.max_range == 81.83


def test_robotlaser1_fields(log_path):
    s = read_log(log_path).scans[1]
    assert s.kind == "ROBOTLASER1" and s.t == 200.25 and s.ipc_t == 200.0
    assert s.angle_min == -1.5 and s.angle_increment == 0.5 and s.max_range == 20.0
    np.testing.assert_array_equal(s.ranges, np.array([1.0, np.inf, 2.5], np.float32))
    np.testing.assert_array_equal(s.remissions, np.array([0.7, 0.8], np.float32))
    np.testing.assert_array_equal(s.laser_pose, [1.0, 2.5, math.pi / 2])
    np.testing.assert_array_equal(s.robot_pose, [1.0, 2.0, math.pi / 2])


def test_odom_and_params(log_path):
    log = read_log(log_path)
    assert len(log.scans) == 2 and len(log.odometry) == 1
    o = log.odometry[0]
    assert (o.t, o.ipc_t, o.tv, o.rv) == (300.5, 300.0, 0.3, 0.1)
    np.testing.assert_array_equal(o.pose, [1.0, 2.0, 0.5])
    assert log.front_laser_offset == 0.25


def test_laser_mount_prefers_robotlaser_poses(log_path):
    log = read_log(log_path)
    # robot at (1, 2) facing +y, laser at (1, 2.5): 0.5 m straight ahead
    np.testing.assert_allclose(log.laser_mount(), (0.5, 0.0, 0.0), atol=1e-12)
    log.scans.pop(1)
    assert log.laser_mount() == (0.25, 0.0, 0.0)    # FLASER only: the PARAM offset


def test_max_range_override_and_limit(log_path):
    log = read_log(log_path, max_range=2.0, limit=1)
    assert len(log.scans) == 1
    np.testing.assert_array_equal(log.scans[0].ranges, np.array([1.0, np.inf, np.inf, np.inf], np.float32))


@pytest.mark.parametrize(("n", "increment"), [(180, math.pi / 180), (181, math.pi / 180),
                                              (360, math.pi / 360), (361, math.pi / 360)])
def test_flaser_beam_spacing(n, increment):
    angle_min, inc = flaser_geometry(n)
    assert angle_min == -math.pi / 2 and inc == pytest.approx(increment, abs=1e-15)


def test_malformed_line_names_the_line(tmp_path):
    path = tmp_path / "bad.log"
    path.write_text("PARAM a 1\nFLASER 5 1.0 2.0\n")
    with pytest.raises(CarmenError, match="line 2: bad FLASER"):
        read_log(path)


def test_laser_records_mount_is_the_laser_pose_in_the_robot_frame(log_path):
    # ROBOTLASER1 line: robot at (1, 2) facing +y, laser at (1, 2.5) facing +y
    s = read_log(log_path).scans[1]
    np.testing.assert_allclose(s.mount, (0.5, 0.0, 0.0), atol=1e-12)


def test_unknown_and_short_lines_are_skipped_or_named(tmp_path):
    path = tmp_path / "odd.log"
    path.write_text("SYNC 1 2\nODOM 1.0 2.0\n")
    with pytest.raises(CarmenError, match="line 2: bad ODOM"):
        read_log(path)
    path.write_text("SYNC 1 2\nGPS whatever\n")
    log = read_log(path)
    assert log.scans == [] and log.odometry == [] and log.front_laser_offset == 0.0


def test_an_odom_line_with_a_negative_stamp_is_left_out_and_named(tmp_path):
    # seattle's log has one: ODOM ... -1.63023 pippo -1.63023 between good ones
    path = tmp_path / "neg.log"
    path.write_text("ODOM 1 2 0.5 0 0 0 10.0 h 10.0\nODOM 1 2 0.5 0 0 0 -1.6 h -1.6\n"
                    "ODOM 1.5 2 0.5 0 0 0 10.2 h 10.2\n")
    log = read_log(path)
    assert [o.t for o in log.odometry] == [10.0, 10.2]
    assert log.skipped == ["line 2: ODOM timestamp -1.6 is not in [0, 2^32) s"]


def _flaser_log(path, scans):
    """A FLASER log of the given (n,) readings rows, poses at the origin."""
    lines = [f"FLASER {len(r)} {' '.join(f'{v:.3f}' for v in r)} 0 0 0 0 0 0 {k}.0 host {k}.0"
             for k, r in enumerate(scans, start=1)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_band_of_readings_at_the_top_is_the_lasers_no_return_value(tmp_path):
    rng = np.random.default_rng(0)
    rows = rng.uniform(0.5, 20.0, (40, 180))
    rows[:, :10] = 32.767          # 400 of 7200 readings (5.6 %) at one value, nothing beyond
    rows[0, 10] = 32.70            # a reading inside the band's lower neighbour: no return too
    rows[0, 11] = 32.55            # below it: a return
    log = read_log(_flaser_log(tmp_path / "sat.log", rows))
    assert log.saturation == pytest.approx(32.6)      # band [32.7, 32.8) less one band
    first = log.scans[0]
    assert first.max_range == pytest.approx(32.6)
    assert np.isinf(first.ranges[:11]).all() and first.ranges[11] == pytest.approx(32.55)
    assert np.isfinite(log.scans[1].ranges[10:]).all()


@pytest.mark.parametrize("far", [
    np.linspace(25.0, 45.0, 400),     # far readings spread over 20 m: walls, not one value
    np.full(20, 32.767),              # a band of 0.3 %: too few to be the laser's limit
])
def test_readings_without_a_band_at_the_top_stay_returns(tmp_path, far):
    rng = np.random.default_rng(1)
    rows = rng.uniform(0.5, 20.0, (40, 180))
    rows.reshape(-1)[:len(far)] = far
    log = read_log(_flaser_log(tmp_path / "spread.log", rows))
    assert log.saturation is None
    assert log.scans[0].max_range == pytest.approx(81.83)
    assert all(np.isfinite(s.ranges).all() for s in log.scans)


def test_a_band_with_readings_beyond_it_is_not_a_limit(tmp_path):
    rng = np.random.default_rng(2)
    rows = rng.uniform(0.5, 20.0, (40, 180))
    rows[:, :10] = 32.767
    rows[:, 10] = 40.0 + rng.uniform(0.0, 5.0, 40)  # 40 readings (0.56 %) beyond the band: a real wall
    assert read_log(_flaser_log(tmp_path / "wall.log", rows)).saturation is None


def test_max_range_given_by_hand_skips_the_detection(tmp_path):
    rows = np.random.default_rng(3).uniform(0.5, 20.0, (40, 180))
    rows[:, :10] = 32.767
    log = read_log(_flaser_log(tmp_path / "hand.log", rows), max_range=81.83)
    assert log.saturation is None
    assert log.scans[0].ranges[0] == pytest.approx(32.767)
