"""python -m fastslam.evaluate: scores printed as a table or JSON, errors as one line and an exit code."""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from fastslam import evaluate
from fastslam.eval.trajectory import TrajectoryScores, apply_alignment
from fastslam.io.trajectory_files import write_trajectory


def moved(poses: np.ndarray, angle: float, shift: tuple[float, float]) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return apply_alignment(np.array([[c, -s], [s, c]]), np.array(shift), poses)


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


def test_table_lines():
    s = TrajectoryScores(matched=12, ate_rmse=0.12345, ate_mean=0.1, ate_max=0.5, rpe_trans=0.01,
                         rpe_rot=1.5, rpe_delta=2)
    lines = evaluate.format_table(s).splitlines()
    assert lines[0].split() == ["matched", "poses", "12"]
    assert lines[1].endswith("0.1235") and lines[4].startswith("RPE trans rmse [m / 2 pose]")
    assert lines[5].split()[-1] == "1.5000"
    assert len({len(line) for line in lines}) == 1                  # one column of values


def test_cli_options_change_the_matching(tmp_path, capsys):
    write_trajectory(tmp_path / "ref.txt", [0.0, 1.0, 2.0], [[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    write_trajectory(tmp_path / "est.txt", [0.5, 1.5], [[0.5, 0, 0], [1.5, 0, 0]])
    ref, est = str(tmp_path / "ref.txt"), str(tmp_path / "est.txt")
    assert evaluate.main([ref, est]) == 1                            # 0.5 s from every reference pose
    assert "no estimate pose within 0.05 s" in capsys.readouterr().err
    assert evaluate.main([ref, est, "--max-dt", "0.5", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["matched"] == 2
    assert evaluate.main([ref, est, "--interpolate", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["matched"] == 2 and out["ate_max"] == pytest.approx(0.0, abs=1e-12)


def test_cli_relations_json_and_tum_estimate(tmp_path, capsys, relations_case):
    write_trajectory(tmp_path / "est.tum", relations_case.t, relations_case.poses, fmt="tum")
    assert evaluate.main(["--relations", str(relations_case.path), str(tmp_path / "est.tum"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["relations"] == 2 and out["trans_mean"] == pytest.approx(0.25, abs=1e-12)
    assert out["rot_max"] == pytest.approx(45.0, abs=1e-9)


def test_cli_lists_the_worst_relations(tmp_path, capsys, relations_case):
    write_trajectory(tmp_path / "est.txt", relations_case.t, relations_case.poses)
    args = ["--relations", str(relations_case.path), str(tmp_path / "est.txt"), "--worst", "1"]
    assert evaluate.main(args) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[3] == "worst 1:" and len(lines) == 6
    assert lines[5].split() == ["0.500", "2.500", "1.000", "0.500", "45.00", "0.50"]
    assert evaluate.main(args + ["--json"]) == 0
    worst = json.loads(capsys.readouterr().out)["worst"]
    assert len(worst) == 1 and worst[0]["t1"] == 0.5 and worst[0]["trans"] == pytest.approx(0.5, abs=1e-12)


@pytest.mark.parametrize("args", [["ref.txt", "est.txt", "--worst", "2"],
                                  ["--relations", "r.txt", "est.txt", "--worst", "-1"]])
def test_worst_needs_relations_and_a_count(args, capsys):
    with pytest.raises(SystemExit) as stop:
        evaluate.main(args)
    assert stop.value.code == 2 and "--worst" in capsys.readouterr().err


def test_cli_relations_errors(tmp_path, capsys, relations_case):
    write_trajectory(tmp_path / "est.txt", relations_case.t, relations_case.poses)
    (tmp_path / "bad.relations").write_text("1 2 3\n")
    assert evaluate.main(["--relations", str(tmp_path / "bad.relations"), str(tmp_path / "est.txt")]) == 2
    assert "bad.relations:1" in capsys.readouterr().err
    assert evaluate.main(["--relations", str(tmp_path / "none"), str(tmp_path / "est.txt")]) == 2
    assert "cannot read relations" in capsys.readouterr().err


def test_scores_that_cannot_be_computed_exit_1_with_valid_json(tmp_path, capsys):
    (tmp_path / "ref.txt").write_text("1 0 0 0\n2 1 0 0\n")
    (tmp_path / "one.txt").write_text("1 0 0 0\n")          # one matched pose: no relative error
    assert evaluate.main([str(tmp_path / "ref.txt"), str(tmp_path / "one.txt"), "--json"]) == 1
    out, err = capsys.readouterr()
    scores = json.loads(out)                                 # NaN would not parse as JSON
    assert scores["rpe_trans"] is None and scores["rpe_rot"] is None and scores["ate_rmse"] == 0.0
    assert err.strip() == "error: rpe_trans, rpe_rot could not be computed (too few matched poses?)"


def test_binary_files_and_bad_options_are_one_line_errors(tmp_path, capsys):
    (tmp_path / "ref.txt").write_text("1 0 0 0\n2 1 0 0\n")
    (tmp_path / "bin.txt").write_bytes(bytes(range(256)))
    (tmp_path / "nan.txt").write_text("1 0 0 0\n2 nan 0 0\n")
    cases = [([str(tmp_path / "ref.txt"), str(tmp_path / "bin.txt")], f"error: {tmp_path / 'bin.txt'} is not a "
              "text file of trajectory lines"),
             ([str(tmp_path / "ref.txt"), str(tmp_path / "nan.txt")], f"error: {tmp_path / 'nan.txt'}:2: NaN or "
              "infinite values: '2 nan 0 0'"),
             ([str(tmp_path / "ref.txt"), str(tmp_path / "ref.txt"), "--delta", "0"],
              "error: --delta must be at least 1 (got 0) and --max-dt at least 0 (got 0.05)"),
             (["--relations", str(tmp_path / "bin.txt"), str(tmp_path / "ref.txt")],
              f"error: {tmp_path / 'bin.txt'} is not a text file of relations lines")]
    for args, line in cases:
        assert evaluate.main(args) == 2
        assert capsys.readouterr().err.strip() == line


def _colour_pixels(png, rgb, box):
    from PIL import Image

    with Image.open(png) as img:
        px = np.asarray(img.convert("RGB"), dtype=np.int32)[box]
    return int(np.sum(np.abs(px - np.array(rgb)).sum(axis=2) < 40))


TAB_RED, TAB_GREEN = (214, 39, 40), (44, 160, 44)   # matplotlib's tab:red, tab:green


def test_plot_draws_the_aligned_estimate_over_the_reference(tmp_path):
    th = np.cumsum(np.random.default_rng(9).uniform(-0.3, 0.3, 200))
    ref = np.column_stack([np.cumsum(np.cos(th)), np.cumsum(np.sin(th)), th])   # a 200 m winding path
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


def test_a_reader_closing_the_output_early_gets_one_line_not_a_traceback(tmp_path):
    # `evaluate ... | head`: the pipe is closed before the tool writes its table
    t = np.arange(2000.0)
    poses = np.stack([t * 0.1, np.zeros_like(t), np.zeros_like(t)], axis=1)
    write_trajectory(tmp_path / "ref.txt", t, poses)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    read, write = os.pipe()
    os.close(read)
    with open(write, "wb") as closed:
        done = subprocess.run([sys.executable, "-m", "fastslam.evaluate", str(tmp_path / "ref.txt"),
                               str(tmp_path / "ref.txt")], stdout=closed, stderr=subprocess.PIPE, env=env,
                              timeout=120, check=False)
    err = done.stderr.decode().strip().splitlines()
    assert done.returncode == 1
    assert err == ["evaluate.py: output closed by its reader; stopped"]
