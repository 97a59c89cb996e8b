"""match_prior_arc: the step's odometry model in its own terms (rot1, trans, rot2) for the
searches' prior and the gate, by hand."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastslam.config import ConfigError, SlamConfig
from fastslam.filter.motion import OdometryArc, odometry_arc
from fastslam.filter.proposal import motion_arc, within_motion
from fastslam.match.search import pick

# a 3 m step straight ahead from the origin: std-devs 0.3 rad, 0.3 m, 0.3 rad
STRAIGHT = OdometryArc(0.0, 3.0, 0.0, 0.3, 0.3, 0.3)
PREDICTED = np.array([3.0, 0.0, 0.0])
# The step turned 0.6 rad (2 std-devs) left in its first turn: on the arc, 4 squared std-devs.
# Along and across the predicted heading (0.3 m along, 0.9 m across, 0.42 rad) it lies
# 0.52 m short, 1.69 m left and 0.6 rad turned: 3.05 + 3.54 + 2.0 = 8.6.
ON_ARC = np.array([3 * math.cos(0.6), 3 * math.sin(0.6), 0.6])
LINEAR_STD = np.array([0.3, 0.9, math.hypot(0.3, 0.3)])


def test_the_cost_is_the_squared_std_devs_of_the_steps_own_terms():
    """From (1, 2) heading 0.5: step rot1 0.3, trans 2, rot2 -0.1, std-devs 0.1, 0.2, 0.05.
    The pose reached by rot1 0.4, trans 1.8, rot2 -0.05 is one std-dev off in each: 3."""
    arc = OdometryArc(0.3, 2.0, -0.1, 0.1, 0.2, 0.05)
    pred = np.array([1 + 2 * math.cos(0.8), 2 + 2 * math.sin(0.8), 0.7])
    pose = np.array([1 + 1.8 * math.cos(0.9), 2 + 1.8 * math.sin(0.9), 0.85])
    assert arc.cost(*pose, *pred) == pytest.approx(3.0, abs=1e-9)
    assert arc.cost(*pred, *pred) == pytest.approx(0.0, abs=1e-12)
    wide = arc.widened(2.0)
    assert wide.cost(*pose, *pred) == pytest.approx(0.75, abs=1e-9) and wide.rot1 == 0.3


def test_a_reversing_step_is_measured_backwards():
    """Reversing 1 m from the origin facing +x (rot1 0, trans -1): ending 1.1 m behind
    costs only the travel, (0.1 / 0.05)^2 = 4; turning its first turn 0.1 rad left (the
    back swings right) costs (0.1 / 0.1)^2 = 1."""
    arc = OdometryArc(0.0, -1.0, 0.0, 0.1, 0.05, 0.1)
    pred = np.array([-1.0, 0.0, 0.0])
    assert arc.cost(-1.1, 0.0, 0.0, *pred) == pytest.approx(4.0, abs=1e-9)
    swung = np.array([-math.cos(0.1), -math.sin(0.1), 0.1])
    assert arc.cost(*swung, *pred) == pytest.approx(1.0, abs=1e-9)


def test_the_gate_passes_a_long_step_turned_wrong_that_the_gaussian_refuses():
    poses, predicted = ON_ARC[None], PREDICTED[None]
    assert STRAIGHT.cost(*ON_ARC, *PREDICTED) == pytest.approx(4.0, abs=1e-9)
    assert within_motion(poses, predicted, LINEAR_STD, 2.5, STRAIGHT)[0]            # 2 std-devs
    assert not within_motion(poses, predicted, LINEAR_STD, 2.5)[0]                   # 2.93
    assert within_motion(poses, predicted, LINEAR_STD, 3.0)[0]


def test_the_search_picks_the_candidate_on_the_arc_where_the_gaussian_picks_another():
    """Two candidates score alike, the rest nothing: the one on the arc (4 squared
    std-devs there, 8.6 in the Gaussian) and one as far left but not short (5.2 on the
    arc, 5.5 in the Gaussian). Candidates: 3 x 3 cells of 0.262 m round the middle."""
    cell = (3.0 - ON_ARC[0]) / 2
    centre = np.array([[ON_ARC[0] + cell, ON_ARC[1], 0.6]])
    scores = np.zeros((1, 1, 9), dtype=np.int64)
    scores[0, 0, [3, 5]] = 10                         # (x index, y index) (0, 1) and (2, 1)
    turns = np.zeros(1)
    args = (scores, centre, turns, 1, cell, PREDICTED[None], LINEAR_STD, 100)
    np.testing.assert_allclose(pick(*args, arc=STRAIGHT)[0], ON_ARC, atol=1e-9)
    np.testing.assert_allclose(pick(*args)[0], [3.0, ON_ARC[1], 0.6], atol=1e-9)


def test_motion_arc_is_for_long_odometry_steps_and_floored():
    cfg = SlamConfig(match_prior="motion", motion_model="odometry", match_prior_arc=0.2, match_floor_xy=0.05,
                     match_floor_theta=0.05, srr=0.1, srt=0.0, str=0.0, stt=0.1)
    arc = motion_arc(cfg, np.zeros(3), np.array([0.5, 0.0, 0.0]))
    # sigmas: rot1 0 -> 0.05 / 0.5 = 0.1 rad (0.05 m across), trans 0.05, rot2 0 -> 0.05
    assert arc == pytest.approx(OdometryArc(0.0, 0.5, 0.0, 0.1, 0.05, 0.05))
    assert motion_arc(cfg, np.zeros(3), np.array([0.15, 0.0, 0.3])) is None                # 0.15 m < 0.2
    assert motion_arc(cfg.replace(match_prior_arc=0.0), np.zeros(3), np.array([0.5, 0.0, 0.0])) is None
    assert motion_arc(cfg.replace(motion_model="assignment"), np.zeros(3), np.array([0.5, 0.0, 0.0])) is None
    with pytest.raises(ValueError, match="travel"):
        odometry_arc(np.zeros(3), np.array([0.0, 0.0, 1.0]), (0.1, 0.1, 0.1, 0.1), 0.05, 0.05)
    with pytest.raises(ConfigError, match="match_prior_arc"):
        SlamConfig(match_prior_arc=-1.0)
