"""match_poses: the whole matcher on maps of the pillar room (coarse-to-fine search, then
hill climb or ICP), its fall-backs, and its parameters from the configuration."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.config import SlamConfig
from fastslam.filter.grid import GridMaps
from fastslam.filter.scan import Scan, select_beams
from fastslam.filter.slam import FastSlam
from fastslam.match import MatchParams, match_poses, refine_poses
from fastslam.match.matcher import far_range, free_share, in_long_runs, neighbourhood_flags

ANGLES = np.radians(np.arange(360.0))


def test_free_end_points_count_in_runs_spanning_the_length_or_more():
    local = np.stack([np.arange(8) * 0.3, np.zeros(8)], axis=1)     # returns 0.3 m apart along a wall
    free = np.array([[1, 1, 0, 1, 1, 1, 1, 0],     # runs 0-1 (0.3 m) and 3-6 (0.9 m)
                     [0, 0, 0, 0, 0, 0, 0, 1],     # one return: 0 m
                     [1, 1, 1, 1, 1, 1, 1, 1]], dtype=bool)   # 2.1 m
    np.testing.assert_array_equal(in_long_runs(free, local, 0.8),
                                  [[0, 0, 0, 1, 1, 1, 1, 0], [0] * 8, [1] * 8])
    np.testing.assert_array_equal(in_long_runs(free, local, 0.95)[0], [0] * 8)
    # the share: the runs under 0.8 m left out
    np.testing.assert_allclose(free_share(free, local, MatchParams(free_space=True, short_free=0.8)),
                               [4 / 8, 0 / 8, 8 / 8])
    np.testing.assert_allclose(free_share(free, local, MatchParams(free_space=True)), [6 / 8, 1 / 8, 8 / 8])


def test_matcher_recovers_a_known_offset(mapped_room, scan360):
    slam, _ = mapped_room()
    truth = np.array([0.2, -0.3, 0.4])
    beams = select_beams(scan360(truth), slam.cfg)
    offsets = np.array([[0.2, 0.0, np.radians(5)], [-0.15, 0.12, -np.radians(5)], [0.0, 0.0, 0.0]])
    match = match_poses(slam.grid, truth + offsets, beams, MatchParams.from_config(slam.cfg))
    assert match.trusted.all()
    err = match.poses - truth
    assert np.abs(err[:, :2]).max() < 0.03          # within about half a cell (0.05 m)
    assert np.abs(err[:, 2]).max() < np.radians(1.5)  # the map itself is only so sharp
    assert match.covariance is None                  # the hill climb has none


def test_matcher_falls_back_on_an_empty_map(scan360):
    cfg = SlamConfig(particles=4, seed=0, proposal="scan_match")
    slam = FastSlam(cfg)
    poses = np.array([[0.1, 0.0, 0.0]] * 4)
    match = match_poses(slam.grid, poses, select_beams(scan360(np.zeros(3)), cfg), MatchParams.from_config(cfg))
    assert not match.trusted.any()
    np.testing.assert_array_equal(match.poses, poses)


def test_matcher_falls_back_without_returns(mapped_room):
    slam, pose = mapped_room()
    scan = Scan(ranges=np.full(360, np.inf), angles=ANGLES, range_min=0.12, range_max=3.5)
    match = match_poses(slam.grid, slam.poses, select_beams(scan, slam.cfg), MatchParams.from_config(slam.cfg))
    assert not match.trusted.any()
    np.testing.assert_array_equal(match.poses, slam.poses)


def test_matcher_needs_ten_returns(mapped_room, scan360):
    slam, _ = mapped_room(particles=1)
    truth = np.array([0.2, -0.3, 0.4])
    scan = scan360(truth)
    returns = np.flatnonzero(scan.ranges < 3.5)
    start = truth[None] + [[0.05, 0.0, 0.0]]
    anything = MatchParams(xy_range=0.3, theta_range=0.15, min_score=0.0, min_known=0)   # trusts any match
    for count, matched in ((9, False), (10, True)):
        keep = returns[np.linspace(0, len(returns) - 1, count).astype(int)]
        ranges = np.full(360, np.inf)
        ranges[keep] = scan.ranges[keep]
        beams = select_beams(Scan(ranges=ranges, angles=ANGLES, range_min=0.12, range_max=3.5), slam.cfg)
        assert np.count_nonzero(beams.hit) == count
        assert match_poses(slam.grid, start, beams, anything).trusted.all() == matched


def test_matcher_distrusts_a_map_that_knows_too_little(mapped_room, scan360):
    slam, _ = mapped_room(particles=1)
    truth = np.array([0.2, -0.3, 0.4])
    beams = select_beams(scan360(truth), slam.cfg)
    params = MatchParams.from_config(slam.cfg)
    assert match_poses(slam.grid, truth[None], beams, params).trusted.all()
    strict = MatchParams(beams=params.beams, xy_range=params.xy_range, theta_range=params.theta_range,
                         min_known=10**6)
    match = match_poses(slam.grid, truth[None], beams, strict)
    assert not match.trusted.any()
    assert np.abs(match.poses - truth).max() < 0.05    # the pose is still matched, only not trusted


def test_matcher_with_the_motion_prior_and_icp_recovers_the_truth(mapped_room, scan360):
    slam, _ = mapped_room()
    params = MatchParams.from_config(slam.cfg.replace(match_prior="motion", match_refine="icp"))
    truth = np.array([0.2, -0.3, 0.4])
    beams = select_beams(scan360(truth), slam.cfg)
    centre = np.tile(truth + [0.03, -0.02, 0.02], (3, 1))              # odometry's prediction
    poses = centre + np.array([[0.1, 0.0, 0.05], [-0.08, 0.06, -0.04], [0.0, 0.0, 0.0]])
    match = match_poses(slam.grid, poses, beams, params, prior=(centre, np.array([0.05, 0.05, 0.05])))
    assert match.trusted.all()
    err = match.poses - truth
    assert np.abs(err[:, :2]).max() < 0.015
    assert np.abs(err[:, 2]).max() < np.radians(0.5)


def test_icp_with_covariance_returns_one_per_particle(mapped_room, scan360):
    slam, _ = mapped_room()
    cfg = slam.cfg.replace(match_refine="icp", match_spread="match")
    truth = np.array([0.2, -0.3, 0.4])
    match = match_poses(slam.grid, np.tile(truth, (3, 1)), select_beams(scan360(truth), cfg),
                        MatchParams.from_config(cfg))
    assert match.covariance is not None and match.covariance.shape == (3, 3, 3)
    np.testing.assert_allclose(match.covariance, np.swapaxes(match.covariance, 1, 2))   # symmetric
    assert np.all(np.linalg.eigvalsh(match.covariance) > 0)                               # positive definite
    assert np.all(np.sqrt(match.covariance[:, [0, 1], [0, 1]]) < 0.05)   # a room pins x and y to cm


def test_params_from_the_configuration():
    cfg = SlamConfig(match_beams=30, match_xy_range=0.4, match_theta_range=0.2, match_min_score=0.7,
                     match_min_known=5, match_refine="icp", match_spread="match", match_search_gain=0.3)
    assert MatchParams.from_config(cfg) == MatchParams(beams=30, xy_range=0.4, theta_range=0.2, min_score=0.7,
                                                       min_known=5, refine="icp", covariance=True, search_gain=0.3)
    assert MatchParams.from_config(SlamConfig()) == MatchParams()        # the defaults agree


def test_neighbourhood_flags_by_hand():
    grid = GridMaps(1, (10, 10), 0.1, (0.0, 0.0))
    grid.logodds[0, 5, 5] = 20                     # one wall cell
    grid.logodds[0, 5, 7] = -10                    # known free, two cells from it
    local = np.array([[0.55, 0.55],                # on the wall cell
                      [0.65, 0.45],                # cell (6, 4): diagonal neighbour
                      [0.75, 0.55],                # cell (7, 5): free, no wall within one cell
                      [0.85, 0.85],                # cell (8, 8): unknown
                      [0.05, 0.05]])               # cell (0, 0): the edge, neither
    occupied, free = neighbourhood_flags(grid, np.zeros((1, 3)), local)
    assert occupied.tolist() == [[True, True, False, False, False]]
    assert free.tolist() == [[False, False, True, False, False]]
    # seen from (0.1, 0, 0) every point moves one cell along x
    occupied, free = neighbourhood_flags(grid, np.array([[0.1, 0.0, 0.0]]), local)
    assert occupied.tolist() == [[True, False, False, False, False]]
    assert free.tolist() == [[False, False, False, False, False]]


def test_refine_poses_pulls_a_pose_a_few_cm_off_onto_the_map(mapped_room, scan360):
    slam, _ = mapped_room()
    cfg = slam.cfg.replace(match_refine="icp")
    truth = np.array([0.1, -0.1, 0.2])
    start = truth + np.array([[0.03, -0.02, 0.01]])
    match = refine_poses(slam.grid.view(0), start, select_beams(scan360(truth), cfg), MatchParams.from_config(cfg),
                         (start, np.array([0.05, 0.05, 0.05])))
    assert match.trusted.tolist() == [True] and match.score is not None and match.score[0] > 0.9
    assert np.hypot(*(match.poses[0, :2] - truth[:2])) < 0.01     # from 3.6 cm off
    assert abs(match.poses[0, 2] - truth[2]) < 0.005


def test_refine_poses_trusts_nothing_on_an_empty_map(scan360):
    cfg = SlamConfig(particles=1, seed=0, proposal="scan_match", match_refine="icp")
    slam = FastSlam(cfg)
    start = np.array([[0.1, 0.0, 0.0]])
    match = refine_poses(slam.grid, start, select_beams(scan360(np.zeros(3)), cfg), MatchParams.from_config(cfg),
                         (start, np.full(3, 0.05)))
    assert not match.trusted.any() and match.score is not None and match.score[0] == 0.0


def test_icp_on_more_end_points_than_the_search(mapped_room, scan360):
    slam, _ = mapped_room()
    truth = np.array([0.2, -0.3, 0.4])
    start = np.tile(truth + [0.03, -0.02, 0.02], (3, 1))
    covs = []
    for icp_beams in (0, 360):                      # 0: the search's 60 end points
        cfg = slam.cfg.replace(match_refine="icp", match_spread="match", match_beams=60, match_icp_beams=icp_beams)
        params = MatchParams.from_config(cfg)
        assert params.icp_beams == icp_beams
        match = match_poses(slam.grid, start, select_beams(scan360(truth), cfg), params,
                            prior=(start, np.full(3, 0.5)))
        assert match.trusted.all() and np.abs(match.poses[:, :2] - truth[:2]).max() < 0.015
        assert match.covariance is not None
        covs.append(match.covariance[:, 0, 0])
    # six times the end points (the weak prior aside): about a sixth of the variance
    assert np.all(covs[1] < covs[0] / 4) and np.all(covs[1] > covs[0] / 8)


def test_refine_poses_finds_a_heading_beyond_icps_reach(mapped_room, scan360):
    # 17 degrees off: the room's far walls (2.5 m) move 75 cm, far beyond ICP's 2-cell kernel
    slam, _ = mapped_room()
    truth = np.array([0.1, -0.1, 0.2])
    start = truth + np.array([[0.02, 0.0, 0.3]])
    errors = []
    for theta_range in (0.5, 0.0):                  # 0: three headings one step apart
        cfg = slam.cfg.replace(match_refine="icp", match_theta_range=theta_range)
        match = refine_poses(slam.grid.view(0), start, select_beams(scan360(truth), cfg),
                             MatchParams.from_config(cfg), (start, np.array([0.05, 0.05, 0.2])))
        errors.append(abs(match.poses[0, 2] - truth[2]))
    assert errors[0] < 0.002 and errors[1] > 0.1   # measured 0.0003 and 0.19 rad


def test_far_range_is_the_90th_percentile_of_the_ranges_as_numpy_gives_it():
    angles = np.linspace(-1.0, 1.0, 10)
    ranges = np.arange(1.0, 11.0)                      # (10 - 1) * 0.9 = 8.1: 9 m and a tenth of the way to 10
    local = np.stack([ranges * np.cos(angles), ranges * np.sin(angles)], axis=1)
    assert far_range(local) == pytest.approx(9.1, abs=1e-12)
    rng = np.random.default_rng(0)
    for m in (2, 3, 37, 60, 180, 361):
        local = rng.normal(0.0, 5.0, (m, 2))
        assert far_range(local) == float(np.percentile(np.hypot(local[:, 0], local[:, 1]), 90))   # to the bit


class _Helper:
    """match.matcher.Helper in this process: hands over the last `k` particles."""

    def __init__(self, k: int, fails: bool = False) -> None:
        self.k, self.fails, self.handed = k, fails, []

    def share(self, n: int) -> int:
        return self.k

    def submit(self, grid, args, size) -> None:
        from fastslam.match.matcher import match_some
        self.handed.append((grid.particles, len(args[0])))
        self.part = None if self.fails else match_some(grid, args, size)

    def result(self, grid, args, size):
        from fastslam.match.matcher import match_some
        return match_some(grid, args, size) if self.part is None else self.part


@pytest.mark.parametrize("k", [1, 3, 4, 6])
def test_particles_handed_to_a_helper_match_to_the_same_bits(mapped_room, scan360, k):
    slam, _ = mapped_room(particles=7)
    cfg = slam.cfg.replace(match_prior="motion", match_refine="icp", match_spread="match")
    params = MatchParams.from_config(cfg)
    truth = np.array([0.2, -0.3, 0.4])
    rng = np.random.default_rng(3)
    poses = truth + rng.normal(0.0, [0.06, 0.06, 0.04], (7, 3))
    prior = (poses.copy(), np.array([0.05, 0.05, 0.05]))
    beams = select_beams(scan360(truth), cfg)
    alone = match_poses(slam.grid, poses, beams, params, prior=prior)
    for helper in (_Helper(k), _Helper(k, fails=True)):
        shared = match_poses(slam.grid, poses, beams, params, prior=prior, helper=helper)
        assert helper.handed == [(k, k)]                     # the last k particles, their maps and poses
        for field in ("poses", "trusted", "covariance", "score", "scan_information", "free"):
            np.testing.assert_array_equal(getattr(shared, field), getattr(alone, field))
    assert alone.trusted.sum() >= 5 and np.abs(alone.poses[alone.trusted, :2] - truth[:2]).max() < 0.02
