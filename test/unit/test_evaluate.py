"""Trajectory metrics (ATE after 2D alignment, RPE, time matching) and the evaluate CLI."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from fastslam import evaluate
from fastslam.eval.trajectory import (
    align_2d,
    apply_alignment,
    ate,
    interpolate_poses,
    match_by_time,
    relations_score,
    rpe,
    score,
)
from fastslam.io.trajectory_files import TrajectoryError, read_relations, read_trajectory, write_trajectory


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


def test_trajectory_files_round_trip_and_skip_comments(tmp_path):
    poses = loop(np.random.default_rng(3), 10)
    path = write_trajectory(tmp_path / "a.txt", np.arange(10) * 0.5, poses, comment="two\nlines")
    text = path.read_text()
    assert text.startswith("# two\n# lines\n# t x y theta\n")
    t, p = read_trajectory(path)
    np.testing.assert_array_equal(t, np.arange(10) * 0.5)
    np.testing.assert_array_equal(p, poses)


def test_bad_trajectory_line(tmp_path):
    (tmp_path / "b.txt").write_text("0 1 2 3\n1 2 3\n")
    with pytest.raises(TrajectoryError, match="b.txt:2"):
        read_trajectory(tmp_path / "b.txt")


def test_cli_prints_json(tmp_path, capsys):
    ref = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], float)
    est = ref + [[0, 0.1, 0], [0, -0.1, 0], [0, -0.1, 0], [0, 0.1, 0]]
    t = np.arange(4.0)
    write_trajectory(tmp_path / "ref.txt", t, ref)
    write_trajectory(tmp_path / "est.txt", t + 0.02, moved(est, 0.4, (1, 1)))
    assert evaluate.main([str(tmp_path / "ref.txt"), str(tmp_path / "est.txt"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["matched"] == 4 and out["ate_rmse"] == pytest.approx(0.1, abs=1e-12)
    assert out["rpe_trans"] == pytest.approx(math.sqrt((0.2 ** 2 + 0 + 0.2 ** 2) / 3))


def test_cli_table_and_errors(tmp_path, capsys):
    write_trajectory(tmp_path / "ref.txt", [0.0, 1.0], np.zeros((2, 3)))
    write_trajectory(tmp_path / "far.txt", [5.0, 6.0], np.zeros((2, 3)))
    assert evaluate.main([str(tmp_path / "ref.txt"), str(tmp_path / "ref.txt")]) == 0
    assert "ATE rmse [m]" in capsys.readouterr().out
    assert evaluate.main([str(tmp_path / "ref.txt"), str(tmp_path / "far.txt")]) == 1
    assert evaluate.main([str(tmp_path / "ref.txt"), str(tmp_path / "missing.txt")]) == 2
    assert "cannot read trajectory" in capsys.readouterr().err


# A hand-made relations case. Estimate: (0, 0, 0) at t=0, (1, 0, pi/2) at 1, (1, 1, pi/2) at 2.
HAND_T = np.array([0.0, 1.0, 2.0])
HAND_POSES = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, math.pi / 2], [1.0, 1.0, math.pi / 2]])
# 1: t1 = 0.5 -> (0.5, 0, pi/4) interpolated; t2 = 2.5 -> (1, 1, pi/2) clamped. Seen from the
#    first: ((0.5 + 1) / sqrt2, (-0.5 + 1) / sqrt2, pi/4) = (1.5, 0.5, pi/4) / sqrt2 in x, y.
#    Expected (1, 0, 0): error = est (+) (-1, 0, 0) = est - (cos pi/4, sin pi/4) in x, y
#    = (0.5, -0.5) / sqrt2: translation 0.5 m, rotation 45 deg. (The other order,
#    expected^-1 est, would give |(1.5 / sqrt2 - 1, 0.5 / sqrt2)| = 0.359 m.)
# 2: t1 = -1 -> (0, 0, 0) clamped, t2 = 1 -> (1, 0, pi/2), expected (1, 0, pi/2): error 0.
HAND_RELATIONS = "0.5 2.5 1 0 0 0 0 0\n-1 1 1 0 0 0 0 1.5707963267948966\n"


def test_relations_metric_on_a_hand_made_case(tmp_path):
    (tmp_path / "r.relations").write_text(HAND_RELATIONS)
    s = relations_score(HAND_T, HAND_POSES, read_relations(tmp_path / "r.relations"))
    assert s.relations == 2 and s.outside == 2
    # errors 0.5 and 0 m, 45 and 0 deg: mean, sample std (n - 1 = 1), max
    assert s.trans_mean == pytest.approx(0.25, abs=1e-12)
    assert s.trans_std == pytest.approx(math.sqrt(2 * 0.25 ** 2), abs=1e-12)
    assert s.trans_max == pytest.approx(0.5, abs=1e-12)
    assert s.rot_mean == pytest.approx(22.5, abs=1e-9)
    assert s.rot_std == pytest.approx(math.sqrt(2 * 22.5 ** 2), abs=1e-9)
    assert s.rot_max == pytest.approx(45.0, abs=1e-9)


def test_interpolation_clamps_and_takes_the_short_way_round():
    t = np.array([0.0, 1.0])
    p = np.array([[0.0, 0.0, 3.0], [2.0, 4.0, -3.0]])
    out = interpolate_poses(t, p, [-5.0, 0.5, 7.0])
    np.testing.assert_allclose(out[[0, 2]], p, atol=1e-12)
    np.testing.assert_allclose(out[1, :2], [1.0, 2.0])
    assert abs(out[1, 2]) == pytest.approx(math.pi)


def test_cli_relations_json_and_tum_estimate(tmp_path, capsys):
    (tmp_path / "r.relations").write_text(HAND_RELATIONS)
    write_trajectory(tmp_path / "est.tum", HAND_T, HAND_POSES, fmt="tum")
    assert evaluate.main(["--relations", str(tmp_path / "r.relations"), str(tmp_path / "est.tum"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["relations"] == 2 and out["trans_mean"] == pytest.approx(0.25, abs=1e-12)
    assert out["rot_max"] == pytest.approx(45.0, abs=1e-9)


def test_cli_relations_errors(tmp_path, capsys):
    write_trajectory(tmp_path / "est.txt", HAND_T, HAND_POSES)
    (tmp_path / "bad.relations").write_text("1 2 3\n")
    assert evaluate.main(["--relations", str(tmp_path / "bad.relations"), str(tmp_path / "est.txt")]) == 2
    assert "bad.relations:1" in capsys.readouterr().err
    assert evaluate.main(["--relations", str(tmp_path / "none"), str(tmp_path / "est.txt")]) == 2
    assert "cannot read relations" in capsys.readouterr().err


def test_tum_files_round_trip(tmp_path):
    poses = loop(np.random.default_rng(4), 10)
    path = write_trajectory(tmp_path / "a.tum", np.arange(10) * 0.5, poses, fmt="tum")
    first = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")][0].split()
    assert len(first) == 8 and first[3] == first[4] == first[5] == "0.0"
    t, p = read_trajectory(path)
    np.testing.assert_array_equal(t, np.arange(10) * 0.5)
    np.testing.assert_allclose(p[:, :2], poses[:, :2], rtol=0, atol=0)
    np.testing.assert_allclose(np.cos(p[:, 2] - poses[:, 2]), 1.0, atol=1e-12)


def _colour_pixels(png, rgb, box):
    from PIL import Image

    with Image.open(png) as img:
        px = np.asarray(img.convert("RGB"), dtype=np.int32)[box]
    return int(np.sum(np.abs(px - np.array(rgb)).sum(axis=2) < 40))


TAB_RED, TAB_GREEN = (214, 39, 40), (44, 160, 44)   # matplotlib's tab:red, tab:green


def test_plot_draws_the_aligned_estimate_over_the_reference(tmp_path):
    ref = loop(np.random.default_rng(9), 200)
    t = np.arange(200) * 0.1
    write_trajectory(tmp_path / "ref.txt", t, ref)
    write_trajectory(tmp_path / "moved.txt", t, moved(ref, 1.2, (30.0, -8.0)))   # far away until aligned
    bent = ref.copy()
    bent[100:, 1] += 3.0                                                          # a 3 m step halfway
    write_trajectory(tmp_path / "bent.txt", t, bent)
    left = (slice(None), slice(0, 550))
    assert evaluate.main([str(tmp_path / "ref.txt"), str(tmp_path / "moved.txt"), "--plot",
                          str(tmp_path / "a.png")]) == 0
    assert evaluate.main([str(tmp_path / "ref.txt"), str(tmp_path / "bent.txt"), "--plot",
                          str(tmp_path / "b.png")]) == 0
    from PIL import Image

    with Image.open(tmp_path / "a.png") as img:
        assert (img.format, img.size) == ("PNG", (1100, 480))
    # aligned, the moved copy covers the reference: the green left in the left panel is the
    # legend's (~60 px); the bent copy cannot cover it, so much of the reference stays visible
    red_a, green_a = (_colour_pixels(tmp_path / "a.png", c, left) for c in (TAB_RED, TAB_GREEN))
    green_b = _colour_pixels(tmp_path / "b.png", TAB_GREEN, left)
    assert red_a > 500 and green_a < 0.15 * red_a and green_b > 3 * green_a


def test_plot_is_refused_with_relations(tmp_path, capsys):
    with pytest.raises(SystemExit):
        evaluate.main(["--relations", "r.txt", "e.txt", "--plot", str(tmp_path / "p.png")])
    assert "--plot" in capsys.readouterr().err and not (tmp_path / "p.png").exists()
