"""Trajectory metrics: ATE after the best rigid 2D alignment, RPE, matching by time."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastslam.eval.trajectory import (
    align_2d,
    apply_alignment,
    ate,
    ate_errors,
    interpolate_poses,
    match_by_time,
    relations_score,
    rpe,
    score,
    worst_relations,
)
from fastslam.io.trajectory_files import read_relations


def loop(rng: np.random.Generator, n: int = 100) -> np.ndarray:
    th = np.cumsum(rng.uniform(-0.3, 0.3, n))
    xy = np.cumsum(np.column_stack([np.cos(th), np.sin(th)]), axis=0)
    return np.column_stack([xy, th])


def moved(poses: np.ndarray, angle: float, shift: tuple[float, float]) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return apply_alignment(np.array([[c, -s], [s, c]]), np.array(shift), poses)


def test_rigidly_moved_copy_scores_zero():
    ref = loop(np.random.default_rng(0))
    est = moved(ref, 0.7, (5.0, -2.0))
    assert ate(ref, est) < 1e-9
    trans, rot = rpe(ref, est)
    assert trans < 1e-9 and rot < 1e-9


def test_alignment_recovers_the_inverse_motion():
    ref = loop(np.random.default_rng(1))
    rot, t = align_2d(moved(ref, -2.5, (1.0, 3.0)), ref)
    assert math.atan2(rot[1, 0], rot[0, 0]) == pytest.approx(2.5, abs=1e-12)


def test_alternating_offsets_give_their_size():
    ref = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], float)
    est = ref + [[0, 0.1, 0], [0, -0.1, 0], [0, -0.1, 0], [0, 0.1, 0]]
    # symmetric offsets: the best alignment is the identity, every error is 0.1
    assert ate(ref, est) == pytest.approx(0.1, abs=1e-12)


def test_scaled_square_cannot_be_aligned_away():
    ref = np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]], float)
    est = ref.copy()
    est[:, :2] = 1 + 1.1 * (ref[:, :2] - 1)          # 10 % bigger about the centre
    # no scale in the alignment: each corner is 0.1 * sqrt(2) off
    assert ate(ref, moved(est, 0.3, (4, 4))) == pytest.approx(0.1 * math.sqrt(2), abs=1e-12)


def test_rpe_of_too_long_steps():
    ref = np.column_stack([np.arange(5.0), np.zeros(5), np.zeros(5)])
    est = np.column_stack([1.1 * np.arange(5.0), np.zeros(5), np.zeros(5)])
    trans, rot = rpe(ref, est)
    assert trans == pytest.approx(0.1) and rot == pytest.approx(0.0)
    assert rpe(ref, est, delta=2)[0] == pytest.approx(0.2)


def test_rpe_of_a_constant_heading_error():
    ref = np.column_stack([np.arange(5.0), np.zeros(5), np.zeros(5)])
    est = ref.copy()
    est[:, 2] = 0.1     # same positions, heading off by 0.1: each 1 m step looks rotated by -0.1
    trans, rot = rpe(ref, est)
    assert trans == pytest.approx(2 * math.sin(0.05)) and rot == pytest.approx(0.0, abs=1e-12)


def test_nearest_time_matching_drops_far_poses():
    ref_t, ref = np.array([0.0, 1.0, 2.0]), np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], float)
    t, r, e = match_by_time(ref_t, ref, [0.01, 1.5, 2.04], np.ones((3, 3)), max_dt=0.05)
    np.testing.assert_array_equal(t, [0.01, 2.04])
    np.testing.assert_array_equal(r[:, 0], [0.0, 2.0])


def test_interpolated_matching_wraps_the_heading():
    ref_t, ref = np.array([0.0, 1.0]), np.array([[0, 0, 3.0], [2, 4, -3.0]])
    t, r, _ = match_by_time(ref_t, ref, [0.5, 1.5], np.zeros((2, 3)), interpolate=True)
    np.testing.assert_array_equal(t, [0.5])        # 1.5 lies outside the reference
    np.testing.assert_allclose(r[0, :2], [1.0, 2.0])
    assert abs(r[0, 2]) == pytest.approx(math.pi)   # half-way the short way round, not 0


def test_score_counts_matches():
    ref = loop(np.random.default_rng(2), 20)
    t = np.arange(20) * 0.1
    s = score(t, ref, t + 0.01, moved(ref, 1.0, (2, 2)), max_dt=0.02)
    assert s.matched == 20 and s.ate_rmse < 1e-9 and s.ate_max < 1e-9


def test_ate_errors_of_a_shifted_and_a_bent_copy():
    ref = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], float)
    # a pure shift aligns away: zero errors
    np.testing.assert_allclose(ate_errors(ref, ref + [5.0, -1.0, 0.3]), [0.0, 0.0, 0.0], atol=1e-12)
    # the middle pose 0.3 off across the line: the alignment moves the line by 0.1 towards it
    # (no turn, by symmetry): errors 0.1, 0.2, 0.1
    est = ref + [[0, 0, 0], [0, 0.3, 0], [0, 0, 0]]
    np.testing.assert_allclose(ate_errors(ref, est), [0.1, 0.2, 0.1], atol=1e-12)
    assert ate(ref, est) == pytest.approx(math.sqrt((0.01 + 0.04 + 0.01) / 3))


def test_apply_alignment_turns_positions_and_headings():
    rot = np.array([[0.0, -1.0], [1.0, 0.0]])                   # a quarter turn left
    out = apply_alignment(rot, np.array([1.0, 0.0]), [[1.0, 0.0, 3.0], [0.0, 2.0, 0.0]])
    np.testing.assert_allclose(out, [[1.0, 1.0, 3.0 + np.pi / 2 - 2 * np.pi], [-1.0, 0.0, np.pi / 2]], atol=1e-12)


def test_empty_and_too_short_inputs():
    assert math.isnan(ate(np.zeros((0, 3)), np.zeros((0, 3))))
    assert all(math.isnan(v) for v in rpe(np.zeros((2, 3)), np.zeros((2, 3)), delta=2))
    with pytest.raises(ValueError, match="delta"):
        rpe(np.zeros((4, 3)), np.zeros((4, 3)), delta=0)
    t, r, e = match_by_time([], np.zeros((0, 3)), [1.0], np.zeros((1, 3)))
    assert len(t) == len(r) == len(e) == 0
    s = score([0.0], np.zeros((1, 3)), [9.0], np.zeros((1, 3)))
    assert s.matched == 0 and math.isnan(s.ate_rmse)


def test_nearest_time_matching_prefers_the_earlier_pose_on_a_tie():
    ref_t, ref = np.array([0.0, 1.0]), np.array([[0, 0, 0], [1, 0, 0]], float)
    _, r, _ = match_by_time(ref_t, ref, [0.5], np.zeros((1, 3)), max_dt=0.5)
    np.testing.assert_array_equal(r[:, 0], [0.0])


def test_relations_metric_on_a_hand_made_case(relations_case):
    s = relations_score(relations_case.t, relations_case.poses, read_relations(relations_case.path))
    assert s.relations == 2 and s.outside == 2
    # errors 0.5 and 0 m, 45 and 0 deg: mean, sample std (n - 1 = 1), max
    assert s.trans_mean == pytest.approx(0.25, abs=1e-12)
    assert s.trans_std == pytest.approx(math.sqrt(2 * 0.25 ** 2), abs=1e-12)
    assert s.trans_max == pytest.approx(0.5, abs=1e-12)
    assert s.rot_mean == pytest.approx(22.5, abs=1e-9)
    assert s.rot_std == pytest.approx(math.sqrt(2 * 22.5 ** 2), abs=1e-9)
    assert s.rot_max == pytest.approx(45.0, abs=1e-9)


def test_worst_relations_on_the_hand_made_case(relations_case):
    rel = read_relations(relations_case.path)
    rows = worst_relations(relations_case.t, relations_case.poses, rel, 5)
    # the 0.5 m / 45 deg relation first (t 0.5 -> 2.5, 1 m in 2 s), then the exact one (-1 -> 1, 1 m in 2 s)
    np.testing.assert_allclose(rows, [[0.5, 2.5, 1.0, 0.5, 45.0, 0.5], [-1.0, 1.0, 1.0, 0.0, 0.0, 0.5]],
                               atol=1e-9)
    np.testing.assert_allclose(worst_relations(relations_case.t, relations_case.poses, rel, 1), rows[:1])
    assert worst_relations(relations_case.t, relations_case.poses, rel, 0).shape == (0, 6)
    same_time = np.array([[1.0, 1.0, 0.3, 0.4, 0.0]])      # 0.5 m asked in no time
    row = worst_relations(relations_case.t, relations_case.poses, same_time, 3)[0]
    assert row[2] == pytest.approx(0.5) and row[3] == pytest.approx(0.5) and math.isinf(row[5])


def test_interpolation_clamps_and_takes_the_short_way_round():
    t = np.array([0.0, 1.0])
    p = np.array([[0.0, 0.0, 3.0], [2.0, 4.0, -3.0]])
    out = interpolate_poses(t, p, [-5.0, 0.5, 7.0])
    np.testing.assert_allclose(out[[0, 2]], p, atol=1e-12)
    np.testing.assert_allclose(out[1, :2], [1.0, 2.0])
    assert abs(out[1, 2]) == pytest.approx(math.pi)
