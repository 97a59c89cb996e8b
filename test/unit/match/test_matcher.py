"""Scan-matching proposal and end-point distances (improved mode)."""
from __future__ import annotations

import numpy as np
import pytest

from bench.speed import room_ranges
from fastslam.config import SlamConfig
from fastslam.filter.grid import GridMaps
from fastslam.filter.scan import Beams, Scan, end_points, returns_subset, select_beams, spread_returns
from fastslam.filter.slam import FastSlam
from fastslam.filter.weights import endpoint_distances
from fastslam.match import MatchParams, match_poses
from fastslam.match.refine import icp, surface_normals
from fastslam.match.search import pick, pool_occupied

ANGLES = np.radians(np.arange(360.0))


def _scan(pose: np.ndarray) -> Scan:
    return Scan(ranges=room_ranges(pose, ANGLES), angles=ANGLES, range_min=0.12, range_max=3.5)


def _mapped(particles: int = 3) -> tuple[FastSlam, np.ndarray]:
    """A filter whose maps were built with exact odometry in the bench's room (5 m square + pillar)."""
    cfg = SlamConfig(particles=particles, seed=0, toggle_noise=0, proposal="odometry", max_range=3.5,
                     motion_model="odometry",
                     match_sigma_xy=0.0, match_sigma_theta=0.0, match_xy_range=0.3, match_theta_range=0.15)
    slam = FastSlam(cfg)
    pose = np.zeros(3)
    for i in range(8):
        pose = np.array([-0.3 + 0.05 * i, 0.1 * np.sin(i), 0.1 * i])
        slam.step(pose, _scan(pose))
    return slam, pose


def test_matcher_recovers_a_known_offset():
    slam, _ = _mapped()
    truth = np.array([0.2, -0.3, 0.4])
    beams = select_beams(_scan(truth), slam.cfg)
    offsets = np.array([[0.2, 0.0, np.radians(5)], [-0.15, 0.12, -np.radians(5)], [0.0, 0.0, 0.0]])
    match = match_poses(slam.grid, truth + offsets, beams, MatchParams.from_config(slam.cfg))
    assert match.trusted.all()
    err = match.poses - truth
    assert np.abs(err[:, :2]).max() < 0.03          # within about half a cell (0.05 m)
    assert np.abs(err[:, 2]).max() < np.radians(1.5)  # the map itself is only so sharp


def test_matcher_falls_back_on_an_empty_map():
    cfg = SlamConfig(particles=4, seed=0, proposal="scan_match")
    slam = FastSlam(cfg)
    poses = np.array([[0.1, 0.0, 0.0]] * 4)
    match = match_poses(slam.grid, poses, select_beams(_scan(np.zeros(3)), cfg), MatchParams.from_config(cfg))
    assert not match.trusted.any()
    np.testing.assert_array_equal(match.poses, poses)


def test_matcher_falls_back_without_returns():
    slam, pose = _mapped()
    scan = Scan(ranges=np.full(360, np.inf), angles=ANGLES, range_min=0.12, range_max=3.5)
    match = match_poses(slam.grid, slam.poses, select_beams(scan, slam.cfg), MatchParams.from_config(slam.cfg))
    assert not match.trusted.any()
    np.testing.assert_array_equal(match.poses, slam.poses)


def _one_wall_grid() -> GridMaps:
    grid = GridMaps(2, (40, 40), 0.05, (-1.0, -1.0))
    grid.logodds[:, :, 30] = 50     # a wall of occupied cells, centres at x = 0.525
    grid.logodds[1] = 0             # particle 1 has seen nothing
    return grid


def test_endpoint_distances_are_distances_to_the_nearest_occupied_cell_centre():
    grid = _one_wall_grid()
    beams = Beams(angles=np.array([0.0, 0.0, np.pi / 2]), ranges=np.array([0.425, 0.525, np.inf]),
                  hit=np.array([True, True, False]), free_range=np.array([0.425, 0.525, 0.0]), range_min=0.1)
    poses = np.array([[0.0, 0.025, 0.0], [0.0, 0.025, 0.0]])
    d = endpoint_distances(grid, poses, beams, max_dist=0.3)
    assert d.shape == (2, 3)
    assert d[0, 0] == pytest.approx(0.1, abs=1e-9)
    assert d[0, 1] == pytest.approx(0.0, abs=1e-9)
    assert d[0, 2] == 0.3                            # no return: the cap, left out by the weight
    np.testing.assert_array_equal(d[1], [0.3, 0.3, 0.3])  # empty map: every end point capped


def test_endpoint_distances_cap_far_walls():
    grid = _one_wall_grid()
    beams = Beams(angles=np.array([0.0]), ranges=np.array([0.1]), hit=np.array([True]),
                  free_range=np.array([0.1]), range_min=0.05)
    d = endpoint_distances(grid, np.array([[0.0, 0.025, 0.0]] * 2), beams, max_dist=0.15)
    np.testing.assert_array_equal(d, [[0.15], [0.15]])


def test_pooled_flags_mark_blocks_with_an_occupied_cell():
    rng = np.random.default_rng(0)
    a = rng.integers(-100, 30, (2, 8, 12), dtype=np.int8)
    half, quarter = pool_occupied(a)
    np.testing.assert_array_equal(half, a.reshape(2, 4, 2, 6, 2).max(axis=(2, 4)) > 0)
    np.testing.assert_array_equal(quarter, a.reshape(2, 2, 4, 3, 4).max(axis=(2, 4)) > 0)


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


def _corridor_grid() -> GridMaps:
    """Two walls along x, one cell thick, centres at y = -0.525 and 0.525."""
    grid = GridMaps(1, (60, 120), 0.05, (-3.0, -1.5))
    grid.logodds[0, [19, 40], :] = 50
    return grid


def _wall_points(xs: np.ndarray) -> np.ndarray:
    """End points (robot frame) on both corridor walls seen from the origin."""
    return np.concatenate([np.stack([xs, np.full_like(xs, 0.525)], 1), np.stack([xs, np.full_like(xs, -0.525)], 1)])


def test_icp_leaves_the_corridor_direction_to_the_prior():
    # Along a corridor the scan cannot tell x: the result stays at the prior's centre
    # (odometry's word), while y and the heading come from the walls.
    grid = _corridor_grid()
    local = _wall_points(np.linspace(-1.0, 1.0, 21))
    centre = np.array([[0.03, 0.02, 0.01]])            # odometry: 3 cm ahead, 2 cm and 0.6 deg off
    start = np.array([[0.06, 0.04, 0.02]])             # the particle's sample, further off
    spread = np.array([0.05, 0.05, 0.05])
    normals = np.tile([0.0, 1.0], (len(local), 1))     # walls along x
    pose, _ = icp(grid, start, local, normals, centre, spread)
    assert pose[0, 0] == pytest.approx(0.03, abs=0.003)
    assert abs(pose[0, 1]) < 0.003
    assert abs(pose[0, 2]) < 0.002


def test_icp_refines_a_sub_cell_offset_in_the_room():
    slam, _ = _mapped(particles=1)
    truth = np.array([0.2, -0.3, 0.4])
    beams = select_beams(_scan(truth), slam.cfg)
    sel = spread_returns(beams, 60)
    local = end_points(beams, sel)
    start = truth + np.array([[0.04, -0.03, 0.02]])
    spread = np.array([0.1, 0.1, 0.1])                 # a weak prior, centred on the start
    pose, _ = icp(slam.grid, start, local, surface_normals(beams, sel), start, spread)
    assert np.hypot(*(pose[0, :2] - truth[:2])) < 0.015
    assert abs(pose[0, 2] - truth[2]) < np.radians(0.5)


def test_motion_prior_is_tighter_along_the_heading():
    # Scores flat everywhere: only the prior decides, and the prior along the heading
    # (std 0.02) is tighter than across it (0.2), so the pick moves across, not along.
    poses = np.array([[0.0, 0.0, np.pi / 2]])           # heading +y
    scores = np.zeros((1, 1, 9), dtype=np.int64)
    centre = np.array([[0.05, 0.05, np.pi / 2]])        # 5 cm off in x (across) and y (along)
    out = pick(scores, poses, np.zeros(1), 1, 0.05, centre, np.array([0.02, 0.2, 0.1]), 60)
    np.testing.assert_allclose(out[0], [0.05, 0.05, np.pi / 2])
    out = pick(scores, poses, np.zeros(1), 1, 0.05, centre, np.array([0.2, 0.02, 0.1]), 60)
    np.testing.assert_allclose(out[0], [0.05, 0.05, np.pi / 2])


def test_matcher_with_the_motion_prior_and_icp_recovers_the_truth():
    slam, _ = _mapped()
    params = MatchParams.from_config(slam.cfg.replace(match_prior="motion", match_refine="icp"))
    truth = np.array([0.2, -0.3, 0.4])
    beams = select_beams(_scan(truth), slam.cfg)
    centre = np.tile(truth + [0.03, -0.02, 0.02], (3, 1))              # odometry's prediction
    poses = centre + np.array([[0.1, 0.0, 0.05], [-0.08, 0.06, -0.04], [0.0, 0.0, 0.0]])
    match = match_poses(slam.grid, poses, beams, params, prior=(centre, np.array([0.05, 0.05, 0.05])))
    assert match.trusted.all()
    err = match.poses - truth
    assert np.abs(err[:, :2]).max() < 0.015
    assert np.abs(err[:, 2]).max() < np.radians(0.5)


def test_normals_are_perpendicular_to_the_wall_and_missing_at_gaps():
    # A wall at x = 1 seen from the origin, then one lone return far behind it.
    angles = np.radians(np.array([-10.0, -5.0, 0.0, 5.0, 10.0, 40.0]))
    ranges = np.concatenate([1.0 / np.cos(angles[:5]), [3.0]])
    beams = Beams(angles=angles, ranges=ranges, hit=np.ones(6, dtype=bool), free_range=ranges, range_min=0.1)
    normals = surface_normals(beams, np.arange(6))
    np.testing.assert_array_equal(normals[[0, 4, 5]], np.zeros((3, 2)))   # an end of the scan, a gap
    np.testing.assert_allclose(np.abs(normals[1:4]), [[1.0, 0.0]] * 3, atol=1e-12)


def test_icp_covariance_is_wide_only_along_the_corridor():
    grid = _corridor_grid()
    local = _wall_points(np.linspace(-1.0, 1.0, 21))
    normals = np.tile([0.0, 1.0], (len(local), 1))
    centre = np.zeros((1, 3))
    spread = np.array([0.05, 0.05, 0.05])
    _, info = icp(grid, centre.copy(), local, normals, centre, spread)
    std = np.sqrt(np.diag(np.linalg.inv(info[0])))
    # along: the prior alone; across: 42 end points of sigma 0.05 m and the prior;
    # heading: their lever arms along the walls (the walls' y cancel between the two)
    assert std[0] == pytest.approx(0.05, rel=1e-6)
    assert std[1] == pytest.approx(1 / np.sqrt(42 / 0.05 ** 2 + 1 / 0.05 ** 2), rel=0.01)
    assert std[2] == pytest.approx(1 / np.sqrt((local[:, 0] ** 2).sum() / 0.05 ** 2 + 1 / 0.05 ** 2), rel=0.01)


def test_match_spread_needs_icp():
    from fastslam.config import ConfigError

    with pytest.raises(ConfigError, match="match_spread"):
        SlamConfig(match_spread="match", match_refine="hill")
