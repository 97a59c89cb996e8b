"""What the filter asks of the matcher and which matches it trusts (filter/proposal.py),
and the free-space checks of the matcher and the weights."""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from fastslam.config import SlamConfig
from fastslam.filter.proposal import gate_match, match_request, within_motion
from fastslam.filter.scan import Scan, select_beams
from fastslam.filter.slam import FastSlam
from fastslam.match import Match, MatchParams, match_poses

ANGLES = np.radians(np.arange(360.0))
REAL = dict(match_prior="motion", match_refine="icp", proposal="scan_match", motion_model="odometry")


def _mapped(room_scan: Callable[..., Scan], particles: int = 2) -> FastSlam:
    """Maps of the pillar room (5 m square) built with exact odometry."""
    cfg = SlamConfig(particles=particles, seed=0, toggle_noise=0, proposal="odometry", max_range=3.5,
                     motion_model="odometry", weight_model="likelihood")
    slam = FastSlam(cfg)
    for i in range(8):
        pose = np.array([-0.3 + 0.05 * i, 0.1 * np.sin(i), 0.1 * i])
        slam.step(pose, room_scan(pose, ANGLES))
    return slam


def test_mahalanobis_gate_in_the_frame_of_the_prediction():
    std = np.array([0.1, 0.05, 0.1])
    # 0.2 m along and 0.1 m across a prediction heading +y: (0.2/0.1)^2 + (0.1/0.05)^2 = 8
    predicted = np.array([[1.0, 1.0, math.pi / 2]] * 2)
    poses = np.array([[0.9, 1.2, math.pi / 2], [0.9, 1.2, math.pi / 2 + 0.1]])  # the second also turned 1 std
    np.testing.assert_array_equal(within_motion(poses, predicted, std, 3.0), [True, True])      # 8, 9 <= 9
    np.testing.assert_array_equal(within_motion(poses, predicted, std, 2.9), [True, False])     # 8 <= 8.41 < 9
    np.testing.assert_array_equal(within_motion(poses, predicted, std, 2.8), [False, False])    # 7.84 < 8


def test_match_request_spans_the_motion_model_round_the_prediction():
    cfg = SlamConfig(**REAL, match_window=3, match_xy_range=1.0, match_theta_range=0.5,
                     match_floor_xy=0.05, match_floor_theta=0.05)
    samples, predicted = np.ones((2, 3)), np.zeros((2, 3))
    base = MatchParams.from_config(cfg)
    start, params, prior = match_request(cfg, base, samples, predicted, np.array([0.1, 0.02, 0.3]))
    assert start is predicted and prior is not None and prior[0] is predicted
    np.testing.assert_allclose(prior[1], [0.1, 0.05, 0.3])                  # across floored to 0.05
    assert math.isclose(params.xy_range, 0.3) and params.theta_range == 0.5  # 3 x 0.1; 3 x 0.3 capped
    start, params, _ = match_request(cfg, base, samples, predicted, np.zeros(3))
    assert math.isclose(params.xy_range, 0.15) and math.isclose(params.theta_range, 0.15)  # the floors
    fixed = cfg.replace(match_window=0)
    start, params, _ = match_request(fixed, MatchParams.from_config(fixed), samples, predicted, np.zeros(3))
    assert start is samples and params.xy_range == 1.0                      # fixed, round the samples


def test_gate_withdraws_trust_from_far_poor_matches_only():
    cfg = SlamConfig(**REAL, match_gate=3.0, match_good_score=0.6)
    predicted = np.zeros((3, 3))
    poses = np.array([[0.5, 0.0, 0.0], [0.5, 0.0, 0.0], [0.1, 0.0, 0.0]])   # 5, 5 and 1 std of 0.1 m along
    match = Match(poses=poses, trusted=np.ones(3, dtype=bool), score=np.array([0.5, 0.7, 0.5]))
    gated = gate_match(cfg, match, predicted, np.array([0.1, 0.1, 0.1]))
    np.testing.assert_array_equal(gated.trusted, [False, True, True])       # far and poor; far but good; near


def test_free_space_distrusts_a_match_that_puts_end_points_in_the_room(room_scan):
    slam = _mapped(room_scan)
    truth = np.array([0.0, 0.0, 0.0])
    wrong = truth + [0.6, 0.0, 0.0]       # the walls along x still match; the x = -2.5 wall's end points
    beams = select_beams(room_scan(truth, ANGLES), slam.cfg)   # fall 0.6 m inside the room, on free cells
    base = MatchParams(beams=90, xy_range=0.05, theta_range=0.02, min_score=0.3, min_known=20)
    poses = np.array([wrong, wrong])
    lax = match_poses(slam.grid, poses, beams, base)
    strict = match_poses(slam.grid, poses, beams, MatchParams(**{**base.__dict__, "free_space": True,
                                                                  "max_free": 0.2}))
    assert lax.trusted.all() and lax.score is not None and lax.score.min() >= 0.3
    assert not strict.trusted.any()


def test_likelihood_free_costs_end_points_in_known_free_space(room_scan):
    slam = _mapped(room_scan)
    iy, ix = np.nonzero(slam.grid.particle_map(1) < 0)
    slam.grid.put(1, iy, ix, 0)                       # particle 1 forgot its free space, kept its walls
    scan = room_scan(np.array([-0.6, 0.0, 0.0]), ANGLES)  # seen 0.6 m from where both particles are
    weights = []
    for free in (0.0, 4.5):
        s = FastSlam(slam.cfg.replace(likelihood_free=free))
        s.grid, s.poses = slam.grid.copy(), slam.poses.copy()
        s._observe(select_beams(scan, s.cfg))
        weights.append(s.log_w.copy())
    assert weights[0][0] == weights[0][1]                 # the same walls: the same weight
    assert weights[1][0] < weights[1][1] - 0.2            # end points in its free space cost particle 0
