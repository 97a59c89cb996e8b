"""Plain-text trajectories: 't x y theta' lines, comments, full precision."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.io.trajectory_files import TrajectoryError, read_trajectory, write_trajectory


def loop(rng: np.random.Generator, n: int = 100) -> np.ndarray:
    th = np.cumsum(rng.uniform(-0.3, 0.3, n))
    xy = np.cumsum(np.column_stack([np.cos(th), np.sin(th)]), axis=0)
    return np.column_stack([xy, th])


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


def test_lines_are_written_with_full_precision(tmp_path):
    path = write_trajectory(tmp_path / "p.txt", [0.1], [[1 / 3, -2.0, 1e-17]])
    assert path.read_text().splitlines()[-1] == "0.1 0.3333333333333333 -2.0 1e-17"


def test_reading_sorts_by_time_and_takes_commas_extra_columns_and_trailing_comments(tmp_path):
    (tmp_path / "r.txt").write_text("# t x y theta\n\n2.0 1 1 0.5 99 # late\n1.0,0,0,0\n  1.5 3 4 -1\n")
    t, p = read_trajectory(tmp_path / "r.txt")
    np.testing.assert_array_equal(t, [1.0, 1.5, 2.0])
    np.testing.assert_array_equal(p, [[0, 0, 0], [3, 4, -1], [1, 1, 0.5]])


def test_reading_errors_name_the_file_and_line(tmp_path):
    (tmp_path / "n.txt").write_text("0 1 2 3\n1 2 x 4\n")
    with pytest.raises(TrajectoryError, match=r"n.txt:2: not numbers: '1 2 x 4'"):
        read_trajectory(tmp_path / "n.txt")
    with pytest.raises(TrajectoryError, match="cannot read trajectory"):
        read_trajectory(tmp_path / "missing.txt")
    (tmp_path / "e.txt").write_text("# nothing yet\n")
    t, p = read_trajectory(tmp_path / "e.txt")
    assert t.shape == (0,) and p.shape == (0, 3)


def test_writing_needs_one_pose_per_time(tmp_path):
    with pytest.raises(ValueError, match="3 times but 2 poses"):
        write_trajectory(tmp_path / "w.txt", [0.0, 1.0, 2.0], np.zeros((2, 3)))
    assert not (tmp_path / "w.txt").exists()


def test_tum_files_round_trip(tmp_path):
    poses = loop(np.random.default_rng(4), 10)
    path = write_trajectory(tmp_path / "a.tum", np.arange(10) * 0.5, poses, fmt="tum")
    first = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")][0].split()
    assert len(first) == 8 and first[3] == first[4] == first[5] == "0.0"
    t, p = read_trajectory(path)
    np.testing.assert_array_equal(t, np.arange(10) * 0.5)
    np.testing.assert_allclose(p[:, :2], poses[:, :2], rtol=0, atol=0)
    np.testing.assert_allclose(np.cos(p[:, 2] - poses[:, 2]), 1.0, atol=1e-12)
