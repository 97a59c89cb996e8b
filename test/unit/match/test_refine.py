"""The matcher's last stage: the interpolated evidence, hill climbing, surface normals and
ICP with the odometry prior (and its covariance)."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.config import SlamConfig
from fastslam.filter.grid import GridMaps
from fastslam.filter.scan import Beams, end_points, select_beams, spread_returns
from fastslam.match.matcher import MatchParams, _icp
from fastslam.match.refine import (
    ICP_ITERATIONS,
    _bilinear_scores,
    hill_climb,
    icp_fit,
    prior_information,
    surface_normals,
)


def _corridor_grid() -> GridMaps:
    """Two walls along x, one cell thick, centres at y = -0.525 and 0.525."""
    grid = GridMaps(1, (60, 120), 0.05, (-3.0, -1.5))
    grid.logodds[0, [19, 40], :] = 50
    return grid


def _wall_points(xs: np.ndarray) -> np.ndarray:
    """End points (robot frame) on both corridor walls seen from the origin."""
    return np.concatenate([np.stack([xs, np.full_like(xs, 0.525)], 1), np.stack([xs, np.full_like(xs, -0.525)], 1)])


def test_bilinear_evidence_by_hand():
    grid = GridMaps(1, (4, 4), 1.0, (0.0, 0.0))
    grid.put(0, [1, 1], [1, 2], [100, -100])           # centre (1.5, 1.5); a free cell: no evidence, not negative
    cand = np.zeros((1, 1, 3))
    # at the centre: 100; half a cell right, towards the free cell: 50; on the corner of four cells: 25
    for point, value in (([1.5, 1.5], 100.0), ([2.0, 1.5], 50.0), ([1.0, 1.0], 25.0), ([3.5, 3.5], 0.0)):
        got = _bilinear_scores(grid, cand, np.array([point]))
        assert got.shape == (1, 1) and got[0, 0] == pytest.approx(value)
    both = _bilinear_scores(grid, cand, np.array([[1.5, 1.5], [1.0, 1.0]]))
    assert both[0, 0] == pytest.approx(125.0)           # summed over end points


def test_hill_climb_moves_end_points_onto_a_wall():
    grid = GridMaps(1, (40, 40), 0.05, (-1.0, -1.0))
    grid.logodds[0, :, 30] = 50                         # a wall along y, cell centres at x = 0.525
    local = np.stack([np.full(21, 0.5), np.linspace(-0.5, 0.5, 21)], 1)   # a wall seen 0.5 m ahead
    start = np.array([[-0.02, 0.1, 0.0]])               # end points at x = 0.48: 0.1 of the peak each
    before = _bilinear_scores(grid, start[:, None], local)[0, 0]
    pose = hill_climb(grid, start.copy(), local, 0.02)
    after = _bilinear_scores(grid, pose[:, None], local)[0, 0]
    assert before == pytest.approx(0.1 * 50 * 21)
    # steps of 2.5 cm: -0.02 -> 0.005 -> 0.03, then the halved steps find nothing better along x
    assert pose[0, 0] == pytest.approx(0.03, abs=1e-9)
    assert after >= 0.9 * 50 * 21 - 1e-3                 # end points 0.1 cell from the wall's centres
    assert abs(pose[0, 2]) <= 6 * 0.02 / 8              # at most one heading step per iteration


def test_icp_leaves_the_corridor_direction_to_the_prior():
    # Along a corridor the scan cannot tell x: the result stays at the prior's centre
    # (odometry's word), while y and the heading come from the walls.
    grid = _corridor_grid()
    local = _wall_points(np.linspace(-1.0, 1.0, 21))
    centre = np.array([[0.03, 0.02, 0.01]])            # odometry: 3 cm ahead, 2 cm and 0.6 deg off
    start = np.array([[0.06, 0.04, 0.02]])             # the particle's sample, further off
    spread = np.array([0.05, 0.05, 0.05])
    normals = np.tile([0.0, 1.0], (len(local), 1))     # walls along x
    pose, _, _ = icp_fit(grid, start, local, normals, centre, spread)
    assert pose[0, 0] == pytest.approx(0.03, abs=0.003)
    assert abs(pose[0, 1]) < 0.003
    assert abs(pose[0, 2]) < 0.002


def test_icp_refines_a_sub_cell_offset_in_the_room(mapped_room, scan360):
    slam, _ = mapped_room(particles=1)
    truth = np.array([0.2, -0.3, 0.4])
    beams = select_beams(scan360(truth), slam.cfg)
    sel = spread_returns(beams, 60)
    local = end_points(beams, sel)
    start = truth + np.array([[0.04, -0.03, 0.02]])
    spread = np.array([0.1, 0.1, 0.1])                 # a weak prior, centred on the start
    pose, _, _ = icp_fit(slam.grid, start, local, surface_normals(beams, sel), start, spread)
    assert np.hypot(*(pose[0, :2] - truth[:2])) < 0.015
    assert abs(pose[0, 2] - truth[2]) < np.radians(0.5)


def test_icp_on_an_empty_map_goes_to_the_prior_and_returns_its_information():
    grid = GridMaps(1, (40, 40), 0.05, (-1.0, -1.0))
    local = np.array([[0.5, 0.0], [0.0, 0.5], [-0.3, 0.2]])
    centre = np.array([[0.1, -0.1, 0.0]])
    spread = np.array([0.05, 0.1, 0.2])                # along (x, heading 0), across (y), heading
    pose, info, _ = icp_fit(grid, np.array([[0.2, 0.1, 0.3]]), local, np.zeros((3, 2)), centre, spread)
    np.testing.assert_allclose(pose, centre, atol=1e-12)      # a quadratic: one Gauss-Newton step
    np.testing.assert_allclose(info[0], np.diag([400.0, 100.0, 25.0]), atol=1e-9)


def test_prior_information_turns_with_the_heading_as_the_icp_prior_does():
    # heading 90 degrees: along is y (1/0.05^2 = 400), across is x (1/0.1^2 = 100)
    grid = GridMaps(2, (40, 40), 0.05, (-1.0, -1.0))
    centre = np.array([[0.1, -0.1, np.pi / 2], [0.0, 0.0, np.pi / 6]])
    spread = np.array([0.05, 0.1, 0.2])
    got = prior_information(centre, spread)
    np.testing.assert_allclose(got[0], np.diag([100.0, 400.0, 25.0]), atol=1e-9)
    local = np.array([[0.5, 0.0], [0.0, 0.5]])
    _, info, _ = icp_fit(grid, centre, local, np.zeros((2, 2)), centre, spread)   # empty maps: the prior alone
    np.testing.assert_allclose(got, info, atol=1e-9)


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
    _, info, _ = icp_fit(grid, centre.copy(), local, normals, centre, spread)
    std = np.sqrt(np.diag(np.linalg.inv(info[0])))
    # along: the prior alone; across: 42 end points of sigma 0.05 m and the prior;
    # heading: their lever arms along the walls (the walls' y cancel between the two)
    assert std[0] == pytest.approx(0.05, rel=1e-6)
    assert std[1] == pytest.approx(1 / np.sqrt(42 / 0.05 ** 2 + 1 / 0.05 ** 2), rel=0.01)
    assert std[2] == pytest.approx(1 / np.sqrt((local[:, 0] ** 2).sum() / 0.05 ** 2 + 1 / 0.05 ** 2), rel=0.01)


def test_icp_fit_on_an_empty_map_is_the_cost_of_end_points_not_found():
    # Nothing in reach: each end point costs (2 cells * 0.05 m / 0.05 m)^2 = 4; the first
    # step reaches the prior's centre, so the fit (before the last step) has no prior term.
    assert ICP_ITERATIONS >= 2
    grid = GridMaps(1, (40, 40), 0.05, (-1.0, -1.0))
    local = np.array([[0.5, 0.0], [0.0, 0.5], [-0.3, 0.2]])
    centre = np.array([[0.1, -0.1, 0.0]])
    _, _, fit = icp_fit(grid, np.array([[0.2, 0.1, 0.3]]), local, np.zeros((3, 2)), centre,
                        np.array([0.05, 0.1, 0.2]))
    assert fit[0] == pytest.approx(3 * 4.0)


def test_icp_fit_of_end_points_on_the_walls_is_the_prior_alone():
    grid = _corridor_grid()
    local = _wall_points(np.linspace(-1.0, 1.0, 21) + 0.025)       # on cell centres: zero residuals
    normals = np.tile([0.0, 1.0], (len(local), 1))
    centre = np.array([[0.05, 0.0, 0.0]])                         # odometry 5 cm ahead, along the corridor
    _, _, fit = icp_fit(grid, np.zeros((1, 3)), local, normals, centre, np.array([0.05, 0.05, 0.05]))
    # along the corridor nothing but the prior: x reaches 0.05 in the first step, so the
    # last iteration starts there, on the walls, at the prior's centre
    assert fit[0] == pytest.approx(0.0, abs=1e-6)


def test_icp_fit_refines_several_starts_of_one_map_as_separate_calls_do():
    grid = _corridor_grid()
    local = _wall_points(np.linspace(-1.0, 1.0, 21))
    normals = np.tile([0.0, 1.0], (len(local), 1))
    starts = np.array([[0.0, 0.03, 0.01], [0.02, -0.02, -0.01]])
    centre = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]])
    spread = np.array([0.05, 0.05, 0.05])
    pose, info, fit = icp_fit(grid, starts, local, normals, centre, spread, maps=np.array([0, 0]))
    for i in range(2):
        one, one_info, one_fit = icp_fit(grid, starts[i:i + 1], local, normals, centre[i:i + 1], spread)
        np.testing.assert_allclose(pose[i], one[0], atol=1e-12)
        np.testing.assert_allclose(info[i], one_info[0], atol=1e-9)
        assert fit[i] == pytest.approx(one_fit[0])


def test_icp_steps_go_most_of_the_rest_of_the_way_to_a_thick_walls_centre_line():
    # A wall two cells thick (centres x = 0.525 and 0.575), end points 0.5 m ahead, a prior
    # too wide to matter. The first step's target is the two centres weighed by
    # exp(-ex^2 / 2) at ex = -0.5 and -1.5 cells from the end points:
    # (0.8825 * 0.5 + 0.3247 * 1.5) / 1.2072 = 0.769 cells = 0.0384 m. The target moves
    # with the end points, so each later step leaves a part of the rest (here a quarter).
    grid = GridMaps(1, (40, 40), 0.05, (-1.0, -1.0))
    grid.logodds[0, :, 30:32] = 50
    local = np.stack([np.full(21, 0.5), np.linspace(-0.5, 0.5, 21)], 1)
    normals = np.tile([1.0, 0.0], (21, 1))
    wide = np.array([10.0, 10.0, 10.0])
    rest = []
    for steps in (1, 2, 3, 4):
        pose, _, _ = icp_fit(grid, np.zeros((1, 3)), local, normals, np.zeros((1, 3)), wide, iterations=steps)
        assert abs(pose[0, 1]) < 1e-9 and abs(pose[0, 2]) < 1e-6
        rest.append(0.05 - pose[0, 0])
    w_near, w_far = np.exp(-0.125), np.exp(-1.125)
    assert 0.05 - rest[0] == pytest.approx(0.05 * (0.5 * w_near + 1.5 * w_far) / (w_near + w_far), rel=1e-3)
    assert all(0 < later < 0.3 * earlier for earlier, later in zip(rest, rest[1:]))
    assert rest[3] < 2e-4
    with pytest.raises(ValueError, match="iterations=0"):
        icp_fit(grid, np.zeros((1, 3)), local, normals, np.zeros((1, 3)), wide, iterations=0)


def test_match_params_carry_the_icp_iterations(repo_root):
    cfg = SlamConfig.from_yaml(repo_root / "config" / "real.yaml", {"match_icp_iterations": 5})
    assert MatchParams.from_config(cfg).icp_iterations == 5
    assert MatchParams.from_config(SlamConfig()).icp_iterations == ICP_ITERATIONS == 3


def test_icp_from_the_prior_leaves_the_ghost_of_a_wall():
    # The map holds each wall twice, the copy 0.3 m further out (a wall drawn at a wrong
    # pose). From a start 0.3 m off the end points lie on the copies: a local minimum
    # the ICP stays in (its prior pulls 400 against the walls' 16800 per m); started
    # from the prior's centre as well, the fit there (zero) wins over the ghost's
    # (the prior's (0.3 / 0.05)^2 = 36).
    grid = GridMaps(1, (60, 120), 0.05, (-3.0, -1.5))
    grid.logodds[0, [19, 40], :] = 50                 # walls at y = -0.525 and 0.525
    grid.logodds[0, [13, 46], :] = 50                 # their copies at y = -0.825 and 0.825
    xs = np.linspace(-1.0, 1.0, 21) + 0.025
    local = np.stack([xs, np.full_like(xs, 0.525)], 1)  # one wall seen: its copy is 0.3 m beyond it
    normals = np.tile([0.0, 1.0], (len(local), 1))
    centre = np.zeros((1, 3))
    start = np.array([[0.0, 0.3, 0.0]])
    spread = np.array([0.05, 0.05, 0.05])
    alone, _ = _icp(grid, start, local, normals, centre, spread, MatchParams(icp_from_prior=False))
    both, _ = _icp(grid, start, local, normals, centre, spread, MatchParams(icp_from_prior=True))
    assert alone[0, 1] > 0.25                          # held by the ghost
    np.testing.assert_allclose(both[0], [0.0, 0.0, 0.0], atol=1e-6)
