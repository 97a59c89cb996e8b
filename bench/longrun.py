"""A long simulated run (`make bench longrun`): the office loop driven again and again
for 30 simulated minutes, faster than real time, with the time per update and the
memory sampled every 5 simulated minutes (docs/benchmarks.md)."""
from __future__ import annotations

import argparse
import resource
import sys
import time
from typing import Any

import numpy as np

from bench.common import ROOT
from fastslam import simrun
from fastslam.config import SlamConfig
from fastslam.filter.slam import FastSlam, StepInfo
from fastslam.sim.route import load_route
from fastslam.sim.sim import Simulation


def current_rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize() / 2**20


def longrun_suite(minutes: float = 30.0, config: str = "config/slam.yaml") -> list[dict[str, Any]]:
    """The office loop, 20 times over at most, for `minutes` of simulated time."""
    route = np.concatenate([load_route(ROOT / "worlds" / "office.route.yaml")] * 20)
    rows: list[dict[str, Any]] = []
    window: list[float] = []
    mark = [300.0]
    print(f"{'sim min':>7} {'updates':>7} {'ms/update':>9} {'p95':>6} {'RSS MB':>7} {'maps MB':>8} {'grid':>9}")

    def sample(sim: Simulation, slam: FastSlam, info: StepInfo) -> None:
        window.append(info.seconds)
        if sim.time < mark[0]:
            return
        mark[0] += 300.0
        h, w = slam.grid.shape
        row = {"sim_min": round(sim.time / 60), "updates": slam.updates,
               "ms_median": 1000 * float(np.median(window)), "ms_p95": 1000 * float(np.percentile(window, 95)),
               "rss_mb": current_rss_mb(), "maps_mb": slam.grid.nbytes / 2**20, "grid": f"{h}x{w}"}
        rows.append(row)
        window.clear()
        print(f"{row['sim_min']:>7} {row['updates']:>7} {row['ms_median']:>9.1f} {row['ms_p95']:>6.1f} "
              f"{row['rss_mb']:>7.1f} {row['maps_mb']:>8.1f} {row['grid']:>9}", flush=True)

    start = time.perf_counter()
    simrun.run("office", SlamConfig.from_yaml(ROOT / config, {"seed": 0}), route=route, seed=0,
               max_time=minutes * 60, on_update=sample)
    print(f"{minutes:.0f} simulated minutes in {time.perf_counter() - start:.0f} s wall")
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=30.0, help="simulated minutes")
    parser.add_argument("--config", default="config/slam.yaml")
    args = parser.parse_args(argv)
    longrun_suite(args.minutes, args.config)
    return 0


if __name__ == "__main__":
    sys.exit(main())
