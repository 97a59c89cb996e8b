"""The matcher on its own, on the first Intel scans (bench.matcher)."""
from __future__ import annotations

import numpy as np
import pytest

from bench.matcher import intel_scans, match_errors
from fastslam.config import SlamConfig


@pytest.fixture(autouse=True)
def intel_log(dev_data):
    """bench.matcher reads the Intel log of the development data: fail, naming it, if it is missing."""
    dev_data("intel-corrected.log.gz")


def _median_mm(repo_root, overrides: dict) -> float:
    cfg = SlamConfig.from_yaml(repo_root / "config" / "real.yaml", overrides)
    err = match_errors(cfg, intel_scans(150), seed=0)
    assert len(err) > 140                                  # nearly every match trusted
    return 1000 * float(np.median(np.hypot(err[:, 0], err[:, 1])))


def test_icp_with_the_motion_prior_lands_closer_than_the_hill_climb(repo_root):
    # measured: 20.1 mm against 27.9 mm (150 scans, seed 0; ICP on 200 returns)
    icp = _median_mm(repo_root, {})
    hill = _median_mm(repo_root, {"match_prior": "window", "match_refine": "hill", "match_spread": "fixed",
                                  "match_window": 0, "match_gate": 0, "match_recover": 0, "match_loop": 0})
    assert icp < 23.0
    assert icp < hill - 4.0
