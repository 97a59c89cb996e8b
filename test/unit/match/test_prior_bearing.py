"""match_prior_bearing: the ICP's odometry prior centred the step's travel out along the
bearing the search found, by hand and along a corridor."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastslam.config import ConfigError, SlamConfig
from fastslam.filter.grid import GridMaps
from fastslam.filter.scan import Beams
from fastslam.match import matcher
from fastslam.match.matcher import MatchParams, match_poses
from fastslam.match.refine import icp_fit, prior_on_bearing

# A 2 m step from (1, 1) the odometry turned to bearing 0.3 rad; the search found bearing 0.
ORIGIN = np.array([[1.0, 1.0]])
CENTRE = np.array([[1 + 2 * math.cos(0.3), 1 + 2 * math.sin(0.3), 0.3]])


def test_the_centre_moves_so_its_foot_on_the_found_bearing_lies_the_travel_out():
    """Turned 0.3 rad: the centre goes 2 / cos(0.3) out on its own bearing, to (3, 1 + 2 tan 0.3),
    whose foot on the line y = 1 is (3, 1): 2 m from the start. The heading stays."""
    pick = np.array([[2.9, 1.0, 0.0]])
    out = prior_on_bearing(CENTRE, ORIGIN, pick, 0.5)
    assert out[0] == pytest.approx([3.0, 1 + 2 * math.tan(0.3), 0.3], abs=1e-12)
    assert CENTRE[0, 0] == pytest.approx(1 + 2 * math.cos(0.3))   # the input is left alone


def test_turns_beyond_the_limit_count_as_the_limit():
    """The search's bearing 1.0 rad from the odometry's (and one behind the start, 2.4 rad):
    both scaled by 1 / cos(0.5) = 1.139 at max_turn 0.5."""
    for bearing in (-0.7, math.pi - 0.6):
        pick = np.array([[1 + math.cos(bearing), 1 + math.sin(bearing), 0.0]])
        out = prior_on_bearing(CENTRE, ORIGIN, pick, 0.5)
        assert out[0, :2] == pytest.approx(ORIGIN[0] + (CENTRE[0, :2] - ORIGIN[0]) / math.cos(0.5), abs=1e-12)


def test_a_turn_on_the_spot_or_a_pick_at_the_start_keeps_the_centre():
    """Under 5 cm of travel, or a pick 3 cm from the start, there is no bearing to go by."""
    short = np.array([[1.04, 1.0, 0.5]])
    pick = np.array([[1.0, 1.04, 0.5]])
    assert np.array_equal(prior_on_bearing(short, ORIGIN, pick, 0.5), short)
    at_start = np.array([[1.03, 1.0, 0.0]])
    assert np.array_equal(prior_on_bearing(CENTRE, ORIGIN, at_start, 0.5), CENTRE)


def _corridor_beams() -> Beams:
    """Returns from both walls of a corridor along x (y = -0.525 and 0.525), seen from the
    origin facing +x, every 2 degrees, up to 2.5 m along it."""
    angles = np.radians(np.concatenate([np.arange(12.0, 169.0, 2.0), np.arange(-168.0, -11.0, 2.0)]))
    ranges = 0.525 / np.abs(np.sin(angles))
    hit = np.abs(ranges * np.cos(angles)) <= 2.5
    return Beams(angles=angles, ranges=ranges, hit=hit, free_range=np.zeros(len(angles)), range_min=0.1)


def _corridor_grid() -> GridMaps:
    grid = GridMaps(1, (60, 120), 0.05, (-3.0, -1.5))
    grid.logodds[0, [19, 40], :] = 50                       # wall cells centred at y = -0.525, 0.525
    return grid


# The robot went 1 m straight along the corridor, from (-1, 0) to the origin; the odometry
# turned the step 0.2 rad. The walls fix y and the heading, not x.
STEP_ORIGIN = np.array([[-1.0, 0.0]])
PREDICTED = np.array([[-1 + math.cos(0.2), math.sin(0.2), 0.0]])
SPREAD = np.array([0.3, 0.3, 0.3])


def test_along_a_corridor_the_icp_keeps_the_steps_travel():
    """With the Gaussian about the prediction (isotropic) the ICP stops at its foot on the
    corridor's axis, 1 - cos(0.2) = 2 cm short; centred along the found bearing, on the truth."""
    xs = np.linspace(-2.0, 2.0, 41)
    local = np.concatenate([np.stack([xs, np.full_like(xs, side)], 1) for side in (0.525, -0.525)])
    normals = np.tile([0.0, 1.0], (len(local), 1))         # every end point on a wall along x
    pick = np.array([[-0.01, 0.0, 0.0]])                   # the search: on the axis
    plain, _, _ = icp_fit(_corridor_grid(), pick, local, normals, PREDICTED, SPREAD)
    bent = prior_on_bearing(PREDICTED, STEP_ORIGIN, pick, 0.5)
    moved, _, _ = icp_fit(_corridor_grid(), pick, local, normals, bent, SPREAD)
    assert plain[0] == pytest.approx([math.cos(0.2) - 1, 0.0, 0.0], abs=1e-3)
    assert moved[0] == pytest.approx([0.0, 0.0, 0.0], abs=1e-3)


def test_the_matcher_hands_its_icp_the_prior_on_the_searched_bearing(monkeypatch):
    """match_poses with the step's start: the ICP's prior centre is prior_on_bearing of the
    searches' pick (its start); without the start, or at 0, the prediction."""
    seen = []

    def icp(grid, start, local, normals, centre, spread, params):
        seen.append((start.copy(), centre.copy()))
        return start, np.tile(np.eye(3), (len(start), 1, 1))

    monkeypatch.setattr(matcher, "_icp", icp)
    for bearing, origin in ((0.5, STEP_ORIGIN), (0.0, STEP_ORIGIN), (0.5, None)):
        params = MatchParams(beams=60, xy_range=0.5, theta_range=0.1, min_score=0.2, min_known=0, refine="icp",
                             icp_beams=120, prior_bearing=bearing)
        match_poses(_corridor_grid(), PREDICTED.copy(), _corridor_beams(), params, prior=(PREDICTED, SPREAD),
                    origin=origin)
    (pick, centre), (_, plain), (_, no_start) = seen
    assert abs(pick[0, 1]) < 0.03                           # the walls put the search on the axis ...
    assert centre == pytest.approx(prior_on_bearing(PREDICTED, STEP_ORIGIN, pick, 0.5), abs=1e-12)
    assert centre[0, 0] == pytest.approx(0.0, abs=0.01)      # ... and the prior the travel out along it
    assert np.array_equal(plain, PREDICTED) and np.array_equal(no_start, PREDICTED)


def test_the_configuration():
    cfg = SlamConfig(proposal="scan_match", match_refine="icp", match_prior="motion", match_prior_bearing=0.5)
    assert MatchParams.from_config(cfg).prior_bearing == 0.5
    assert MatchParams.from_config(SlamConfig()).prior_bearing == 0.0
    with pytest.raises(ConfigError, match="match_prior_bearing"):
        SlamConfig(match_prior_bearing=0.5)                 # the assignment's proposal has no ICP prior
    with pytest.raises(ConfigError, match="match_prior_bearing"):
        SlamConfig(proposal="scan_match", match_refine="icp", match_prior="motion", match_prior_bearing=2.0)
