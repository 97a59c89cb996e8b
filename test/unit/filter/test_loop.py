"""A loop closed along the path (filter/loop.py, loop_spread): the jump's spread by hand,
the loop's start, the scans kept, and the filter's maps written again."""
from __future__ import annotations

import math
from typing import Callable

import numpy as np
import pytest

from fastslam.config import ConfigError, SlamConfig
from fastslam.filter import trimmed
from fastslam.filter.grid import QMAX
from fastslam.filter.loop import ScanStore, loop_start, nearest_distances, spread_jump
from fastslam.filter.scan import Beams, Scan, select_beams
from fastslam.filter.slam import TRIM_GROUPS, FastSlam
from fastslam.filter.tiles import TileMaps
from fastslam.geometry import transform_points

ANGLES = np.radians(np.arange(360.0))
REAL = dict(match_prior="motion", match_refine="icp", proposal="scan_match", motion_model="odometry")


def _line(xs, y=0.0, theta=0.0):
    return np.array([[x, y, theta] for x in xs], dtype=float)


def test_each_row_moves_by_its_share_of_the_travel_since_the_loop_s_start():
    # rows 1..3 1 m apart; the last row jumped 0.4 m in y: row 1 stays, row 2 moves half, row 3 all of it
    path = np.vstack([_line([0.0, 1.0, 2.0, 3.0]), [[4.0, 0.4, 0.0]]])
    out = spread_jump(path, 1, np.array([4.0, 0.0, 0.0]), np.array([4.0, 0.4, 0.0]))
    np.testing.assert_allclose(out, [[0, 0, 0], [1, 0, 0], [2, 0.2, 0], [3, 0.4, 0], [4, 0.4, 0]], atol=1e-12)


def test_each_step_turns_by_its_share_of_the_jump_s_turn_and_the_rest_is_spread_by_travel():
    # a quarter turn at (4, 0): row 2 (1 m behind it) must land at (4, -1) turned 90 degrees; the two steps
    # (0 -> 1, 1 -> 2, 1 m each) turn by the shares at their middles (1/4 and 3/4 of 90 degrees): row 1 at
    # (1 + cos 22.5, sin 22.5), row 2 at that + (cos 67.5, sin 67.5); then each row moves by its share
    # (0, 1/2, 1) of the gap from there to (4, -1)
    path = np.vstack([_line([1.0, 2.0, 3.0]), [[4.0, 0.0, math.pi / 2]]])
    out = spread_jump(path, 0, np.array([4.0, 0.0, 0.0]), np.array([4.0, 0.0, math.pi / 2]))
    one = np.array([1 + math.cos(math.pi / 8), math.sin(math.pi / 8)])
    two = one + [math.cos(3 * math.pi / 8), math.sin(3 * math.pi / 8)]
    gap = np.array([4.0, -1.0]) - two
    np.testing.assert_array_equal(out[0], path[0])
    np.testing.assert_allclose(out[1], [*(one + gap / 2), math.pi / 4], atol=1e-12)   # (2.7706, -0.7706)
    np.testing.assert_allclose(out[2], [4.0, -1.0, math.pi / 2], atol=1e-12)
    np.testing.assert_array_equal(out[3], path[3])


def _square(side=10.0, step=0.5):
    """A loop round a square from (0, 0), anticlockwise, back at its start."""
    corners = np.array([[0, 0], [side, 0], [side, side], [0, side], [0, 0]], dtype=float)
    pts = [a + (b - a) * t for a, b in zip(corners[:-1], corners[1:]) for t in np.arange(0, 1, step / side)]
    return np.c_[np.array(pts), np.zeros(len(pts))]


def test_the_loop_starts_at_the_pose_nearest_the_place_found_long_enough_ago():
    path = np.vstack([_square(), [[0.1, 0.3, 0.0]]])     # round the square, then found 0.32 m from its start
    assert loop_start(path, radius=3.0, recent=5.0) == (0, "")
    shifted = np.vstack([[[-1.0, 0.0, 0.0]], path])        # a pose before it: the start is still (0, 0)
    assert loop_start(shifted, radius=3.0, recent=5.0)[0] == 1
    start, why = loop_start(path, radius=0.3, recent=5.0)
    assert start is None and "0.32 m" in why                # nothing of the path near the place found


def test_no_loop_start_when_the_path_came_back_to_an_older_place_in_between():
    # first leg to (10, 0); round the square's left part back through (0, 0), seen before the start, then on
    # below and back up to (10, 0.3): the loop from (10, 0) was anchored at (0, 0) on the way
    there = np.c_[np.arange(0.0, 10.0, 0.5), np.zeros(20), np.zeros(20)]
    up = np.c_[np.full(20, 10.0), np.arange(0.0, 10.0, 0.5), np.zeros(20)]
    left = np.c_[np.arange(10.0, 0.0, -0.5), np.full(20, 10.0), np.zeros(20)]
    down = np.c_[np.zeros(40), np.arange(10.0, -10.0, -0.5), np.zeros(40)]
    right = np.c_[np.arange(0.0, 10.0, 0.5), np.full(20, -10.0), np.zeros(20)]
    back = np.c_[np.full(20, 10.0), np.arange(-10.0, 0.0, 0.5), np.zeros(20)]
    path = np.vstack([there, up, left, down, right, back, [[10.0, 0.3, 0.0]]])
    start, why = loop_start(path, radius=1.0, recent=5.0)
    assert start is None and "came back" in why
    assert loop_start(path[20:], radius=1.0, recent=5.0) == (1, "")   # without the first leg: one loop, from (10, 0.5)


def test_nearest_distances_in_chunks_as_at_once():
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(3000, 2)), rng.normal(size=(700, 2))
    want = np.hypot(a[:, None, 0] - b[None, :, 0], a[:, None, 1] - b[None, :, 1]).min(1)
    np.testing.assert_array_equal(nearest_distances(a, b), want)


def _as_sent(room_scan: Callable[..., Scan]) -> Callable[..., Scan]:
    """room_scan with its ranges in float32, as a LaserScan carries them."""
    def scan(pose, angles, stamp=0.0):
        s = room_scan(pose, angles, stamp=stamp)
        return Scan(ranges=s.ranges.astype(np.float32).astype(float), angles=s.angles, range_min=s.range_min,
                    range_max=s.range_max, stamp=s.stamp)
    return scan


def test_the_scans_kept_are_the_beams_given_and_share_their_directions(room_scan):
    cfg = SlamConfig(max_range=3.5)
    store = ScanStore()
    sent = _as_sent(room_scan)
    given = [select_beams(sent(np.array([0.1 * k, 0.0, 0.0]), ANGLES, stamp=float(k)), cfg) for k in range(3)]
    for b in given:
        store.append(b)
    assert len(store) == 3
    for k, b in enumerate(given):
        back = store.beams(k)
        for field in ("angles", "ranges", "hit", "free_range"):
            np.testing.assert_array_equal(getattr(back, field), getattr(b, field))
        assert back.mount == b.mount and back.range_min == b.range_min
    assert store.beams(2).angles is store.beams(0).angles
    assert store.nbytes == 3 * 9 * 360 + 360 * 8


def _drifted(room_scan: Callable[..., Scan], spread: bool) -> FastSlam:
    room_scan = _as_sent(room_scan)
    """test_proposal's drifted loop: the pillar room mapped along x with exact odometry
    (rows 0-6, x -0.3 .. 0), then both particles put 0.4 m off in x; at the next update
    (x 0.05) match_loop finds the place again 0.4 m back."""
    cfg = SlamConfig(**REAL, particles=2, seed=0, toggle_noise=0, max_range=3.5, weight_model="likelihood",
                     match_window=3, match_gate=3.5, match_good_score=0.6, match_min_score=0.3,
                     match_min_known=20, match_floor_xy=0.02, match_floor_theta=0.01, match_xy_range=1.0,
                     match_theta_range=0.5, match_loop=0.25, match_loop_xy=1.0, match_loop_theta=0.15,
                     resample_threshold=0.0, loop_spread=spread, loop_spread_radius=0.5, loop_spread_recent=0.1)
    slam = FastSlam(cfg)
    for i in range(7):
        pose = np.array([-0.3 + 0.05 * i, 0.0, 0.0])
        slam.step(pose, room_scan(pose, ANGLES, stamp=float(i)))
    slam.poses[:, 0] += 0.4
    slam.step(np.array([0.05, 0.0, 0.0]), room_scan(np.array([0.05, 0.0, 0.0]), ANGLES, stamp=7.0))
    return slam


def test_a_loop_found_again_is_spread_back_and_every_particle_takes_the_map_written_again(room_scan):
    kept, spread = _drifted(room_scan, False), _drifted(room_scan, True)
    assert kept.loops == spread.loops == 1 and kept.loops_spread == 0 and spread.loops_spread == 1
    before, after = kept.trajectory(), spread.trajectory()
    # the loop starts at row 4 (x -0.1: the pose nearest x 0.05 more than 0.1 m of travel back); rows 4..6
    # 0.05 m apart: row 5 moves half the jump, row 6 all of it (about -0.4 in x), rows 0-4 and 7 stay
    np.testing.assert_array_equal(after[:5], before[:5])
    np.testing.assert_array_equal(after[7], before[7])
    jump = after[6, 1:] - before[6, 1:]
    assert -0.45 < jump[0] < -0.33
    steps = np.hypot(*np.diff(before[4:7, 1:3], axis=0).T)         # the matched poses: about 0.05 m each
    np.testing.assert_allclose(after[5, 1:] - before[5, 1:], jump * steps[0] / steps.sum(), atol=1e-4)
    np.testing.assert_array_equal(spread.trajectory(1), after)                  # every particle's path
    np.testing.assert_array_equal(spread.poses[1], spread.poses[0])
    np.testing.assert_array_equal(spread.log_w, [0.0, 0.0])
    # both particles hold one map: the kept scans written again along the new path, in order
    grid = spread.grid
    assert isinstance(grid, TileMaps)
    np.testing.assert_array_equal(grid.table[1], grid.table[0])
    again = TileMaps(1, grid.shape, grid.resolution, (float(grid.origin[0]), float(grid.origin[1])),
                     l_limit=grid.scale * QMAX)
    again.offset = grid.offset
    again.table = np.zeros((1,) + grid.table.shape[1:], dtype=np.int32)
    cfg = spread.cfg
    steps = again.steps(cfg.l_free, cfg.l_occ, cfg.l_min, cfg.l_max)
    sent = _as_sent(room_scan)
    for k, row in enumerate(after):
        beams = select_beams(sent(np.array([-0.3 + 0.05 * k, 0.0, 0.0]) if k < 7 else np.array([0.05, 0, 0]),
                                       ANGLES, stamp=float(k)), cfg)
        _write(again, row[1:], beams, steps, cfg)
    np.testing.assert_array_equal(grid.particle_map(0), again.particle_map(0))
    assert not np.array_equal(kept.grid.particle_map(0), grid.particle_map(0))


def _write(maps: TileMaps, pose, beams: Beams, steps, cfg: SlamConfig) -> None:
    x, y = transform_points(pose[None], np.array([beams.mount], dtype=np.float64))
    trimmed.update_trimmed(maps, np.concatenate([x, y], axis=1), pose[None, 2, None] + beams.angles[None, :], beams,
                           steps, max_range=cfg.max_range, groups=TRIM_GROUPS,
                           free_step=trimmed.clearing_step(beams.angles, cfg.free_beam_step, cfg.free_beam_spacing))


def test_the_spread_needs_the_likelihood_model_and_without_the_loop_search_does_nothing():
    with pytest.raises(ConfigError, match="loop_spread needs weight_model=likelihood"):
        SlamConfig(**REAL, match_loop=0.25, loop_spread=True, weight_model="assignment")
    SlamConfig(**REAL, loop_spread=True, weight_model="assignment")     # match_loop off: no jump to spread
