"""bench.lineage: the final best particle's ancestors, update by update (FastSlam.trace)."""
from __future__ import annotations

import numpy as np
import pytest

from bench import lineage
from fastslam.carmen_to_bag import convert
from fastslam.config import SlamConfig
from fastslam.io.bag_reader import read_bag
from fastslam.io.carmen_log import read_log
from fastslam.offline import run_bag

SCANS = 60


def test_ancestors_follow_each_resampling_back_by_hand():
    # update 2 put slot 0's particle in slot 1; update 1 put slot 1's in slot 0; update 0 kept slot 1
    parents = [np.array([0, 1, 2]), np.array([1, 1, 0]), np.array([2, 0, 0])]
    assert lineage.ancestors(parents, 1) == ([1, 0, 1], [1, 1, 0])
    assert lineage.ancestors(parents, 0) == ([0, 2, 0], [0, 0, 2])
    assert lineage.ancestors([np.arange(4)] * 3, 3) == ([3, 3, 3], [3, 3, 3])   # never resampled


@pytest.fixture(scope="module")
def seattle_bag(dev_data, tmp_path_factory):
    out = tmp_path_factory.mktemp("lineage") / "seattle.bag"
    convert(read_log(dev_data("seattle-corrected.log.gz"), limit=SCANS), out, odom_noise=1.0, seed=3)
    return out


def test_the_lineage_is_the_path_the_offline_tool_writes(seattle_bag):
    cfg = SlamConfig.from_yaml("config/real.yaml", {"seed": 0, "particles": 12})
    traces: list = []
    result = run_bag(read_bag(seattle_bag), cfg, trace=traces.append)
    assert len(traces) == result.slam.updates > SCANS // 2
    rows = lineage.lineage_rows(traces, result.slam.best)
    path = result.slam.trajectory()
    np.testing.assert_allclose([r.t for r in rows], path[:, 0])
    np.testing.assert_allclose(np.array([r.pose for r in rows]), path[:, 1:], atol=1e-12)
    assert any(tr.resampled for tr in traces)     # the lineage crossed resamplings, not one slot throughout
    assert len({r.slot for r in rows}) > 1
    for tr, r in zip(traces, rows):
        assert r.rank == 1 + np.count_nonzero(tr.weights > tr.weights[r.slot])
        assert r.log_w_step <= 0.0 and tr.log_w_step.max() == 0.0
    matched = [r for r in rows[1:] if r.trusted]
    assert len(matched) > SCANS // 2 and all(0.0 <= r.score <= 1.0 for r in matched)


def test_the_command_prints_a_row_per_update_in_the_window_with_its_error(seattle_bag, capsys):
    gt = f"{seattle_bag}.gt.txt"
    code = lineage.main([str(seattle_bag), "--config", "config/real.yaml", "--seed", "0", "--set", "particles=12",
                         "--from", "0", "--to", "1e9", "--reference", gt])
    out = capsys.readouterr().out.splitlines()
    assert code == 0 and out[0].startswith(lineage.HEADER)
    errors = np.array([float(line.split()[-1]) for line in out[1:]])
    assert len(errors) > SCANS // 2 and np.all(np.isfinite(errors)) and np.all(errors < 1.0)


def test_a_missing_bag_is_one_line_and_exit_2(tmp_path, capsys):
    assert lineage.main([str(tmp_path / "none.bag")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:")
