"""Behaviour pinned: trajectories and maps for fixed seeds.

Refactors (the restructure, the tiled maps) must not change a cell or move a pose.
Each case keeps every particle's map as a hash (exact: int8 cells and the grid's
geometry), the best particle's trajectory and every particle's final pose as numbers,
compared to 1e-6 m / rad: numpy's sin, cos and exp differ in the last bit between CPUs
(AVX-512 machines take other code paths) and numpy versions, while any change of the
algorithm moves poses by far more than that and changes the maps. The expected values
are in golden.json. A change that is meant to alter results regenerates them, on
purpose and in its own commit:

    PYTHONPATH=src:. python test/integration/test_golden.py --record
"""
from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from bench.common import data_path
from fastslam import simrun
from fastslam.config import SlamConfig
from fastslam.geometry import wrap_angle

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = Path(__file__).with_name("golden.json")
INTEL = data_path("intel-corrected.log.gz")
TOLERANCE = 1e-6  # [m, rad]: last-bit differences, amplified over 300 scans, stay far below (2e-9 seen)
SIM_SECONDS = 60.0  # of the turtlebot3_world route: ~300 scans


def fingerprint(slam) -> dict:
    """sha256 of all maps (with their geometry); the best trajectory (T, 4) and the final
    poses (N, 3) as nested lists."""
    h = hashlib.sha256()
    grid = slam.grid
    for a in (np.stack([grid.particle_map(i) for i in range(len(slam.poses))]),
              np.asarray(grid.origin, dtype=np.float64).round(9)):
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    return {"maps": h.hexdigest()[:16], "trajectory": slam.trajectory().round(12).tolist(),
            "poses": slam.poses.round(12).tolist()}


def sim_case(preset: str) -> dict[str, str]:
    cfg = SlamConfig.from_yaml(ROOT / "config" / "slam.yaml")
    if preset != "slam":
        cfg = cfg.replace(**SlamConfig.from_yaml(ROOT / "config" / f"{preset}.yaml").to_dict())
    run = simrun.run("turtlebot3_world", cfg.replace(seed=0), seed=0, max_time=SIM_SECONDS)
    return fingerprint(run.slam)


def intel_case() -> dict[str, str]:
    from bench.modes import intel_run

    cfg = SlamConfig.from_yaml(ROOT / "config" / "real.yaml", {"seed": 0})
    slam = intel_run(cfg, 0, log_path=INTEL, limit=300)[0]
    return fingerprint(slam)


CASES = {"sim_slam": lambda: sim_case("slam"), "sim_burger": lambda: sim_case("burger"),
         "sim_real": lambda: sim_case("real"), "intel_300_real": intel_case}


@pytest.mark.parametrize("name", sorted(CASES))
def test_results_are_bit_identical_to_the_recorded_ones(name):
    if name.startswith("intel") and not INTEL.is_file():
        pytest.fail(f"{INTEL} is missing: shared/data must lie beside the repository")
    expected = json.loads(GOLDEN.read_text())[name]
    got = CASES[name]()
    assert got["maps"] == expected["maps"], "a map changed"
    for key in ("trajectory", "poses"):
        want, have = np.array(expected[key]), np.array(got[key])
        assert have.shape == want.shape, f"{key}: {have.shape} against {want.shape}"
        diff = have - want
        diff[:, -1] = wrap_angle(diff[:, -1])   # the heading, last column: +pi and -pi are one
        assert np.abs(diff).max() <= TOLERANCE, f"{key} moved by {np.abs(diff).max():.3g}"


if __name__ == "__main__":
    if sys.argv[1:] != ["--record"]:
        sys.exit("usage: PYTHONPATH=src:. python test/integration/test_golden.py --record")
    GOLDEN.write_text(json.dumps({k: f() for k, f in sorted(CASES.items())}) + "\n")
    print(f"recorded {GOLDEN}")
