"""Scans: from LaserScan fields to base-frame angles, unusable geometry, the class of each
reading, and the returns the matcher and the likelihood weight use."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.config import SlamConfig
from fastslam.filter.scan import (
    Beams,
    Scan,
    end_points,
    fov_problem,
    in_fov,
    laser_problem,
    returns_subset,
    select_beams,
    spread_returns,
)


def test_from_laser_turns_the_beams_by_the_mount():
    s = Scan.from_laser([1, 2, 3], -0.5, 0.5, 0.1, 5.0, mount=(0.1, 0.2, 1.0), stamp=4.5)
    np.testing.assert_allclose(s.angles, [0.5, 1.0, 1.5])
    assert s.mount == (0.1, 0.2) and s.stamp == 4.5 and s.ranges.dtype == np.float64
    # upside down: the laser's angles run the other way round as seen from above
    s = Scan.from_laser([1, 2, 3], -0.5, 0.5, 0.1, 5.0, mount=(0.1, 0.2, 1.0), upside_down=True)
    np.testing.assert_allclose(s.angles, [1.5, 1.0, 0.5])


def test_from_laser_wraps_the_angles():
    s = Scan.from_laser([1, 1], 3.0, 0.5, 0.1, 5.0)
    np.testing.assert_allclose(s.angles, [3.0, 3.5 - 2 * np.pi])


@pytest.mark.parametrize("args, problem", [
    ((0, 0.0, 0.1, 0.1, 3.0), "empty scan"),
    ((10, 0.0, 0.0, 0.1, 3.0), "angle_increment is 0"),
    ((10, 0.0, float("nan"), 0.1, 3.0), "angle_increment is nan"),
    ((10, 0.0, 0.1, 0.1, 0.0), "range_max=0.0 must exceed"),
    ((10, 0.0, 0.1, 2.0, 1.0), "range_max=1.0 must exceed range_min=2.0"),
    ((10, 0.0, 0.1, 0.1, 3.0, 2.0), "10 ranges but its angles imply 21"),
])
def test_laser_problems(args, problem):
    assert problem in laser_problem(*args)


def test_fence_post_and_reversed_scans_are_fine():
    assert laser_problem(360, 0.0, 2 * np.pi / 360, 0.12, 3.5, 2 * np.pi) is None
    assert laser_problem(360, 0.0, -np.pi / 180, 0.12, 3.5, -np.pi / 180 * 359) is None


def test_select_beams_classifies_every_reading():
    cfg = SlamConfig(max_range=3.0, no_return_range=2.0)
    z = [1.0, 0.05, np.nan, np.inf, 5.0, 4.0, -1.0, 2.999]
    scan = Scan(ranges=np.array(z), angles=np.linspace(-1, 1, 8), range_min=0.1, range_max=5.0, mount=(0.3, 0.0))
    b = select_beams(scan, cfg)
    # return, too short, NaN, inf, at range_max (no return), beyond max_range, negative, return
    np.testing.assert_array_equal(b.hit, [True, False, False, False, False, False, False, True])
    np.testing.assert_array_equal(b.ranges, [1.0, np.inf, np.inf, np.inf, np.inf, 4.0, np.inf, 2.999])
    # a return clears up to itself, a no-return up to no_return_range, a far return up to max_range
    np.testing.assert_array_equal(b.free_range, [1.0, 0.0, 2.0, 2.0, 2.0, 3.0, 0.0, 2.999])
    assert b.range_min == 0.1 and b.mount == (0.3, 0.0)


def test_returns_short_of_mark_range_are_hits_that_clear_to_max_range_only():
    cfg = SlamConfig(max_range=3.0, no_return_range=2.0, weight_model="likelihood", mark_range=4.5)
    z = [1.0, 4.0, 4.5, 5.0, np.inf]
    scan = Scan(ranges=np.array(z), angles=np.linspace(-1, 1, 5), range_min=0.1, range_max=5.0)
    b = select_beams(scan, cfg)
    # a return; past max_range, short of mark_range; at mark_range; at range_max; no return
    np.testing.assert_array_equal(b.hit, [True, True, False, False, False])
    np.testing.assert_array_equal(b.ranges, [1.0, 4.0, 4.5, np.inf, np.inf])
    np.testing.assert_array_equal(b.free_range, [1.0, 3.0, 3.0, 2.0, 2.0])


def test_no_return_clears_at_most_max_range():
    scan = Scan(ranges=np.array([np.inf]), angles=np.zeros(1), range_min=0.1, range_max=5.0)
    assert select_beams(scan, SlamConfig(max_range=3.0, no_return_range=8.0)).free_range[0] == 3.0
    assert select_beams(scan, SlamConfig(max_range=3.0, no_return_range=0.0)).free_range[0] == 0.0


def test_field_of_view_and_beam_step():
    deg = np.array([-90.0, -45.0, 0.0, 45.0, 90.0, 135.0, 350.0])
    scan = Scan(ranges=np.ones(7), angles=np.radians(deg), range_min=0.1, range_max=5.0)
    b = select_beams(scan, SlamConfig(fov_min=-45.0, fov_max=90.0))
    np.testing.assert_allclose(np.degrees(b.angles), [-45, 0, 45, 90, 350])   # 350 deg is -10 deg
    b = select_beams(scan, SlamConfig(fov_min=-45.0, fov_max=90.0, beam_step=2))
    np.testing.assert_allclose(np.degrees(b.angles), [0, 90, 350])           # beams 2, 4, 6 of the scan


def test_in_fov_wraps_and_includes_the_limits():
    cfg = SlamConfig(fov_min=-30.0, fov_max=30.0)
    deg = np.array([-30.0, 30.0, 30.5, 335.0, -335.0, 325.0, 180.0, 0.0])    # 335 is -25, -335 is 25
    np.testing.assert_array_equal(in_fov(np.radians(deg), cfg), [True, True, False, True, True, False, False, True])


def test_fov_problem_describes_the_sweep():
    cfg = SlamConfig(fov_min=-30.0, fov_max=30.0)
    rear = Scan.from_laser(np.ones(91), -np.pi / 4, np.radians(1.0), 0.1, 3.5, mount=(0.0, 0.0, np.pi))
    assert fov_problem(rear, cfg) == ("no beam in the field of view fov_min..fov_max = -30..30 deg "
                                      "(the scan sweeps from 135 to -135 deg in the base frame)")
    front = Scan.from_laser(np.ones(91), -np.pi / 4, np.radians(1.0), 0.1, 3.5)
    assert fov_problem(front, cfg) is None


def _beams(hit: np.ndarray) -> Beams:
    n = len(hit)
    return Beams(angles=np.linspace(-1, 1, n), ranges=np.linspace(1, 2, n), hit=hit, free_range=np.ones(n),
                 range_min=0.1)


def test_spread_returns_hand_computed():
    hit = np.zeros(10, dtype=bool)
    hit[[0, 2, 3, 5, 7, 9]] = True
    # 6 returns, 3 wanted: positions linspace(0, 5, 3) = 0, 2.5, 5 -> returns 0, 2, 5 -> beams 0, 3, 9
    np.testing.assert_array_equal(spread_returns(_beams(hit), 3), [0, 3, 9])
    np.testing.assert_array_equal(spread_returns(_beams(hit), 6), [0, 2, 3, 5, 7, 9])
    np.testing.assert_array_equal(spread_returns(_beams(hit), 60), [0, 2, 3, 5, 7, 9])
    assert len(spread_returns(_beams(np.zeros(4, dtype=bool)), 3)) == 0


def test_returns_subset_spreads_the_returns_evenly():
    hit = np.ones(100, dtype=bool)
    hit[::3] = False                                          # 66 returns
    beams = Beams(angles=np.linspace(-1, 1, 100), ranges=np.linspace(1, 2, 100), hit=hit,
                  free_range=np.ones(100), range_min=0.1)
    sub = returns_subset(beams, 10)
    assert len(sub.ranges) == 10 and sub.hit.all()
    idx = np.searchsorted(beams.angles, sub.angles)
    assert idx[0] == np.flatnonzero(hit)[0] and idx[-1] == np.flatnonzero(hit)[-1]
    assert len(returns_subset(beams, 500).ranges) == 66


def test_end_points_in_the_robot_frame():
    beams = Beams(angles=np.array([0.0, np.pi / 2, np.pi]), ranges=np.array([2.0, 1.0, 0.5]),
                  hit=np.ones(3, dtype=bool), free_range=np.ones(3), range_min=0.1, mount=(0.1, -0.2))
    np.testing.assert_allclose(end_points(beams, np.array([0, 1, 2])), [[2.1, -0.2], [0.1, 0.8], [-0.4, -0.2]],
                               atol=1e-12)
    np.testing.assert_allclose(end_points(beams, np.array([1])), [[0.1, 0.8]], atol=1e-12)
