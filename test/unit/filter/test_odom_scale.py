"""odom_scale: the odometry's scale learnt from the matches, by hand and in the pillar room."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.config import ConfigError, SlamConfig
from fastslam.filter.odom_scale import MAX_SCALE_ERROR, OdometryScale
from fastslam.filter.scan import Scan
from fastslam.filter.slam import FastSlam
from fastslam.geometry import compose, relative

ANGLES = np.radians(np.arange(0.0, 360.0, 2.0))


def info(xx: float = 0.0, yy: float = 0.0) -> np.ndarray:
    return np.diag([xx, yy, 0.0])[None]


def test_the_scale_is_the_ratio_of_the_pinned_matches_travel_to_the_odometrys():
    """prior 1 m; odometry 0.5 m, the match 0.55 m with 0.9 of the information from the scan;
    then 0.5 m again, matched 0.6 m but with 0.8 of it: the prior pulled it, it does not count."""
    scale = OdometryScale(1.0)
    scale.observe(0.5, np.zeros((1, 3)), np.array([[0.55, 0.0, 0.0]]), info(xx=9.0), info(xx=1.0))
    assert scale.travel == pytest.approx((1 + 0.55) / (1 + 0.5), abs=1e-12) and scale.steps == 1
    scale.observe(0.5, np.zeros((1, 3)), np.array([[0.6, 0.0, 0.0]]), info(xx=4.0), info(xx=1.0))
    assert scale.travel == pytest.approx((1 + 0.55) / (1 + 0.5), abs=1e-12) and scale.steps == 1


def test_the_particles_matches_count_as_their_mean_and_along_their_own_travel():
    """Two particles, 0.4 m of odometry: one matched 0.3 m along y (its scan pins y down), the
    other 0.5 m along x (pinned along x); a third pinned only across its travel does not count."""
    scale = OdometryScale(0.0)
    before = np.zeros((3, 3))
    matched = np.array([[0.0, 0.3, 0.0], [0.5, 0.0, 0.0], [0.45, 0.0, 0.0]])
    scan = np.concatenate([info(yy=100.0), info(xx=100.0), info(yy=100.0)])
    scale.observe(0.4, before, matched, scan, np.concatenate([info(1.0, 1.0)] * 3))
    assert scale.travel == pytest.approx((0.3 + 0.5) / 2 / 0.4, abs=1e-12)


def test_reversing_counts_travel_backwards_and_corrected_scales_the_step():
    scale = OdometryScale(0.0)
    facing_y = np.array([[2.0, 1.0, np.pi / 2]])        # reversing 0.5 m by odometry, 0.55 m matched
    scale.observe(-0.5, facing_y, np.array([[2.0, 0.45, np.pi / 2]]), info(yy=1e9), info(yy=1.0))
    assert scale.travel == pytest.approx(1.1, abs=1e-8)
    # a step 1 m ahead and 0.2 m left, turning 0.2 rad, from (1, 2) facing +y: travel scaled, turn kept
    moved = scale.corrected(np.array([1.0, 2.0, np.pi / 2]), np.array([0.8, 3.0, np.pi / 2 + 0.2]))
    np.testing.assert_allclose(moved, [0.78, 3.1, np.pi / 2 + 0.2], atol=1e-8)


def test_short_steps_and_corridors_teach_nothing_and_the_estimate_stays_within_its_bounds():
    scale = OdometryScale(1.0)
    scale.observe(0.04, np.zeros((1, 3)), np.array([[0.08, 0.0, 0.0]]), info(xx=1e9), info(xx=1.0))
    for _ in range(10):   # the scan pins only the across direction: its shift along is the prior's
        scale.observe(0.5, np.zeros((1, 3)), np.array([[0.6, 0.0, 0.0]]), info(yy=1e6), info(xx=1.0, yy=1.0))
    assert scale.travel == 1.0 and scale.steps == 0
    for _ in range(50):   # the scan says twice the travel
        scale.observe(0.5, np.zeros((1, 3)), np.array([[1.0, 0.0, 0.0]]), info(xx=1e9), info(xx=1.0))
    assert scale.travel == 1.0 + MAX_SCALE_ERROR


def test_odom_scale_needs_the_icp_and_the_motion_prior():
    with pytest.raises(ConfigError, match="odom_scale needs"):
        SlamConfig(odom_scale=True)
    with pytest.raises(ConfigError, match="odom_scale_prior"):
        SlamConfig(odom_scale_prior=-1.0)


def _scaled_odometry(truth: np.ndarray, travel: float, turn: float) -> np.ndarray:
    odom = [np.zeros(3)]
    for a, b in zip(truth[:-1], truth[1:]):
        d = relative(a, b)
        odom.append(compose(odom[-1], [d[0] * travel, d[1] * travel, d[2] * turn]))
    return np.array(odom)


@pytest.mark.parametrize("travel, turn", [(1.05, 0.98), (1.0, 1.0), (0.97, 1.02)])
def test_the_filter_learns_the_scale_of_its_odometry_in_the_pillar_room(loop, room_ranges, travel, turn):
    """Odometry reading travel (and turn) times the true motion: the filter learns to scale travel by its inverse."""
    truth = loop(120)
    odom = _scaled_odometry(truth, travel, turn)
    cfg = SlamConfig(particles=5, seed=3, motion_model="odometry", weight_model="likelihood", proposal="scan_match",
                     match_prior="motion", match_window=3.0, match_gate=4.5, match_refine="icp", match_spread="match",
                     match_min_known=20, match_beams=90, linear_update=0.1, angular_update=0.1,
                     odom_scale=True, odom_scale_prior=0.1)
    slam = FastSlam(cfg)
    rng = np.random.default_rng(0)
    for t, (pose, o) in enumerate(zip(truth, odom)):
        ranges = room_ranges(pose, ANGLES) + rng.normal(0, 0.01, len(ANGLES))
        slam.step(o, Scan(ranges=ranges, angles=ANGLES, range_min=0.12, range_max=3.5, stamp=0.2 * t))
    assert slam.odom_scale is not None and slam.odom_scale.steps > 40
    assert slam.odom_scale.travel == pytest.approx(1 / travel, abs=0.01)


def test_a_scan_with_too_few_returns_to_match_teaches_nothing_and_breaks_nothing(room_ranges):
    cfg = SlamConfig(particles=3, seed=0, motion_model="odometry", weight_model="likelihood", proposal="scan_match",
                     match_prior="motion", match_refine="icp", odom_scale=True, odom_scale_prior=0.0)
    slam = FastSlam(cfg)
    pose = np.zeros(3)
    slam.step(pose, Scan(ranges=room_ranges(pose, ANGLES), angles=ANGLES, range_min=0.12, range_max=3.5, stamp=0.0))
    few = np.full(len(ANGLES), np.inf)
    few[:5] = 1.0                                                       # 5 returns: nothing to match
    moved = np.array([0.3, 0.0, 0.0])
    assert slam.step(moved, Scan(ranges=few, angles=ANGLES, range_min=0.12, range_max=3.5, stamp=0.2)).processed
    assert slam.odom_scale is not None and slam.odom_scale.steps == 0 and slam.odom_scale.travel == 1.0
