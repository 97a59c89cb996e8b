"""The improved mode's pieces: log-weights, Neff gating, update gating, map growth,
the odometry motion model."""
from __future__ import annotations

import numpy as np
import pytest

from bench.speed import room_ranges
from fastslam.config import SlamConfig
from fastslam.filter.grid import GridMaps
from fastslam.filter.motion import sample_motion_odometry
from fastslam.filter.resample import neff
from fastslam.filter.scan import Scan
from fastslam.filter.slam import FastSlam
from fastslam.filter.weights import likelihood_log_weights, normalise_log
from fastslam.geometry import wrap_angle

ANGLES = np.radians(np.arange(0.0, 360.0, 4.0))


def _scan(pose: np.ndarray, stamp: float = 0.0) -> Scan:
    return Scan(ranges=room_ranges(pose, ANGLES), angles=ANGLES, range_min=0.12, range_max=3.5, stamp=stamp)


def test_log_weights_normalise_like_direct_weights():
    log_w = np.log(np.array([0.1, 0.3, 0.6, 1e-3]))
    direct = np.exp(log_w) / np.exp(log_w).sum()
    np.testing.assert_allclose(normalise_log(log_w), direct, rtol=1e-12)
    np.testing.assert_allclose(normalise_log(log_w - 500.0), direct, rtol=1e-12)


def test_log_weights_stay_finite_where_direct_computation_underflows():
    log_w = np.array([-2000.0, -2001.0, -2000.0 - np.log(3.0)])
    assert np.exp(log_w).sum() == 0.0                       # direct: 0/0
    np.testing.assert_allclose(normalise_log(log_w), np.array([3.0, 3.0 / np.e, 1.0]) / (4.0 + 3.0 / np.e))
    np.testing.assert_allclose(normalise_log(np.array([-np.inf, 0.0, -np.inf])), [0.0, 1.0, 0.0])
    np.testing.assert_allclose(normalise_log(np.full(4, -np.inf)), [0.25] * 4)


def test_likelihood_log_weights_hand_computed():
    d = np.array([[0.0, 0.05, 10.0], [0.1, 0.1, 0.0]])
    valid = np.array([True, True, False])
    lw = likelihood_log_weights(d, valid, sigma=0.05, max_dist=0.3, gain=0.5)
    np.testing.assert_allclose(lw, [0.5 * -0.5, 0.5 * -4.0])


def _filter(**kw) -> FastSlam:
    base = dict(particles=10, seed=0, motion_model="odometry", weight_model="likelihood")
    return FastSlam(SlamConfig(**{**base, **kw}))


@pytest.mark.parametrize("threshold, spread, expect", [(0.5, 0.1, False), (0.5, 3.0, True), (1.0, 0.0, True)])
def test_neff_gating_resamples_only_below_threshold(threshold, spread, expect):
    slam = _filter(resample_threshold=threshold)
    slam.log_w = -spread * np.arange(10.0)
    w = slam.weights
    before = slam.log_w.copy()
    assert (neff(w) < threshold * 10) == expect or threshold == 1.0
    assert slam._resample(w, neff(w))[0] == expect
    if expect:
        np.testing.assert_array_equal(slam.log_w, np.zeros(10))
    else:
        np.testing.assert_array_equal(slam.log_w, before)   # weights carry over


def test_weights_carry_over_between_updates_without_resampling():
    slam = _filter(resample_threshold=0.01, particles=5, toggle_noise=0)
    slam.step(np.zeros(3), _scan(np.zeros(3), 0.0))
    slam.log_w = np.log(np.array([0.1, 0.2, 0.3, 0.15, 0.25]))
    blind = Scan(ranges=np.full(len(ANGLES), np.inf), angles=ANGLES, range_min=0.12, range_max=3.5, stamp=0.1)
    info = slam.step(np.array([0.05, 0.0, 0.0]), blind)    # nothing to weigh with
    assert info.processed and not info.resampled
    np.testing.assert_allclose(slam.weights, [0.1, 0.2, 0.3, 0.15, 0.25])


def test_update_gating_processes_only_after_enough_motion():
    slam = _filter(linear_update=0.5, angular_update=0.5, temporal_update=-1.0, toggle_noise=0)
    processed = []
    for i in range(8):
        pose = np.array([0.15 * i, 0.0, 0.0])
        processed.append(slam.step(pose, _scan(pose, float(i))).processed)
    # first scan always; then every time odometry accumulated 0.5 m (0.6 m, 1.2 m)
    assert processed == [True, False, False, False, True, False, False, False]
    assert slam.poses[0] == pytest.approx([0.6, 0.0, 0.0])  # the skipped motion was not lost
    turn = slam.step(np.array([1.05, 0.0, 0.6]), _scan(np.array([1.05, 0.0, 0.6]), 8.0))
    assert turn.processed                                   # 0.6 rad >= angular_update


def test_temporal_update_processes_a_still_robot():
    slam = _filter(linear_update=0.5, angular_update=0.5, temporal_update=2.0)
    flags = [slam.step(np.zeros(3), _scan(np.zeros(3), float(t))).processed for t in range(5)]
    assert flags == [True, False, True, False, True]


def test_map_grows_and_keeps_content_at_its_world_place():
    grid = GridMaps(2, (20, 30), 0.1, (-1.5, -1.0))
    marks = np.array([[-1.45, -0.95], [1.45, 0.95], [0.05, 0.05]])
    cells = grid.world_to_cell(marks)
    grid.logodds[1, cells[:, 1], cells[:, 0]] = [11, 22, 33]
    assert grid.grow_to(-4.0, -1.0, 1.0, 6.0)
    x0, y0, x1, y1 = grid.extent
    assert x0 <= -4.0 and y0 <= -1.0 and x1 > 1.0 and y1 > 6.0
    cells = grid.world_to_cell(marks)
    np.testing.assert_array_equal(grid.logodds[1, cells[:, 1], cells[:, 0]], [11, 22, 33])
    assert np.count_nonzero(grid.logodds) == 3
    h, w = grid.shape
    assert (h - 20) >= 10 and (w - 30) >= 15                 # at least half the size: amortised
    assert not grid.grow_to(-3.9, -0.9, 0.9, 5.9)           # already covered: no copy


def test_filter_grows_the_map_instead_of_clipping():
    slam = _filter(map_width=4.0, map_height=4.0, max_range=3.5, toggle_noise=0)
    grew = []
    for i in range(6):
        pose = np.array([0.5 * i, 0.0, 0.0])
        info = slam.step(pose, _scan(pose, float(i)))
        grew.append(info.grew)
        assert not info.clipped
    assert any(grew)
    assert slam.grid.covers(2.5 - 3.5, -3.5, 2.5 + 3.5, 3.5)


@pytest.mark.parametrize("delta", [(1.0, 0.0, np.pi / 2), (-0.5, 0.0, 0.2), (0.3, -0.4, -1.0), (0.0, 0.0, 0.7)])
def test_odometry_model_without_noise_reproduces_the_odometry_delta(delta):
    rng = np.random.default_rng(0)
    prev = np.array([2.0, -1.0, 0.8])
    c, s = np.cos(prev[2]), np.sin(prev[2])
    odom = np.array([prev[0] + c * delta[0] - s * delta[1], prev[1] + s * delta[0] + c * delta[1],
                     prev[2] + delta[2]])
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, np.pi / 2]])
    sample_motion_odometry(poses, prev, odom, (0.1, 0.2, 0.1, 0.2), False, rng)
    # each particle moves by the same robot-frame delta from its own pose
    np.testing.assert_allclose(poses[0], [delta[0], delta[1], wrap_angle(delta[2])], atol=1e-12)
    np.testing.assert_allclose(poses[1], [1.0 - delta[1], 1.0 + delta[0], wrap_angle(np.pi / 2 + delta[2])],
                               atol=1e-12)


def test_odometry_model_noise_scales_with_motion():
    rng = np.random.default_rng(0)
    poses = np.zeros((4000, 3))
    sample_motion_odometry(poses, np.zeros(3), np.array([1.0, 0.0, 0.0]), (0.1, 0.0, 0.0, 0.0), True, rng)
    assert poses[:, 0].mean() == pytest.approx(1.0, abs=0.01)
    assert poses[:, 0].std() == pytest.approx(0.1, rel=0.05)
    assert np.abs(poses[:, 2]).max() == 0.0


def _likelihood_map(free_beam_step: int = 1) -> tuple[FastSlam, np.ndarray, np.ndarray]:
    """One scan of the room written by the likelihood mode (trimmed trace) into 2 maps."""
    slam = FastSlam(SlamConfig(particles=2, seed=0, toggle_noise=0, weight_model="likelihood",
                               free_beam_step=free_beam_step))
    pose = np.array([0.3, -0.2, 0.4])
    slam.step(pose, _scan(pose))
    z = room_ranges(pose, ANGLES)
    a = pose[2] + ANGLES
    ends = pose[:2] + z[:, None] * np.stack([np.cos(a), np.sin(a)], 1)
    mids = pose[:2] + 0.5 * z[:, None] * np.stack([np.cos(a), np.sin(a)], 1)
    ends[z >= 3.4] = np.nan                                  # no return (max_range 3.5): no wall
    return slam, ends, mids


def _values(slam: FastSlam, points: np.ndarray) -> np.ndarray:
    c = slam.grid.world_to_cell(points)
    return slam.grid.logodds[:, c[:, 1], c[:, 0]]          # (N, P)


def _near(slam: FastSlam, points: np.ndarray, reduce=np.min) -> np.ndarray:
    """(N, P) least (or most) log-odds among each point's cell and its 8 neighbours: a
    digital beam line runs from the cell of the origin, so it may pass beside a point."""
    c = slam.grid.world_to_cell(points[np.isfinite(points).all(axis=1)])
    d = np.arange(-1, 2)
    return reduce([slam.grid.logodds[:, c[:, 1] + dy, c[:, 0] + dx] for dy in d for dx in d], axis=0)


def test_trimmed_map_update_marks_end_cells_and_clears_the_beams():
    slam, ends, mids = _likelihood_map()
    assert np.all(_near(slam, ends, np.max) > 0)               # walls at the end cells
    assert np.all(_near(slam, mids) < 0)                 # the middle of every beam is free
    far = np.array([[4.0, 4.0], [-4.0, 3.0]])                # outside the room: never touched
    assert np.all(_values(slam, far) == 0)


def test_free_beam_step_clears_along_every_kth_beam_but_marks_all_end_cells():
    slam, ends, mids = _likelihood_map(free_beam_step=2)
    full, _, _ = _likelihood_map()
    traced = np.arange(len(ANGLES)) % 2 == 0
    assert np.all(_near(slam, mids[traced]) < 0)
    assert np.any(_values(slam, mids[~traced]) == 0)         # untraced beams leave some unknown
    assert np.all(_near(slam, ends[~traced], np.max) > 0)    # ...but their end cells are walls
    assert np.count_nonzero(slam.grid.logodds < 0) < np.count_nonzero(full.grid.logodds < 0)


def test_grow_fraction_sets_the_least_growth_of_a_side():
    for fraction, least in ((0.5, 50), (0.1, 10)):
        g = GridMaps(1, (100, 100), 0.1, (0.0, 0.0))
        g.grow_to(-0.05, 0.0, 9.0, 9.0, fraction=fraction)    # one cell short on the left
        assert g.shape == (100, 100 + least)
        np.testing.assert_allclose(g.origin, [-least * 0.1, 0.0])
