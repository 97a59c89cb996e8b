"""Speed and memory of one filter step (`make bench speed`; docs/benchmarks.md).

For N in {20, 50, 100} and beams in {60, 360}, on a 10 m and a 40 m square map
at 0.05 m, the median milliseconds per full filter step and the peak memory of a fresh
process (each case in its own interpreter, so peak RSS is that case's alone).
"""
from __future__ import annotations

import argparse
import functools
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

from bench.common import in_own_process, progress
from fastslam.config import SlamConfig
from fastslam.filter.scan import Scan
from fastslam.filter.slam import FastSlam
from fastslam.sim.lidar import cast_rays
from fastslam.sim.world import World
from fastslam.sim.world_loader import load_world


def room_ranges(pose: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Exact ranges from pose (3,) in worlds/pillar_room.yaml (the simulator's lidar)."""
    return cast_rays(_pillar_room(), pose, angles)


@functools.lru_cache(maxsize=1)
def _pillar_room() -> World:
    return load_world(Path(__file__).resolve().parents[1] / "worlds" / "pillar_room.yaml")


def speed_case(particles: int, beams: int, size: float, steps: int = 25) -> dict:
    """Runs one case in this process and returns its figures."""
    cfg = SlamConfig(particles=particles, map_width=size, map_height=size, seed=0,
                     beam_step=360 // beams)
    slam = FastSlam(cfg)
    angles = np.radians(np.arange(360.0))
    rng = np.random.default_rng(0)
    times = []
    for i in range(steps):
        pose = np.array([0.02 * i, 0.01 * i, 0.03 * i])
        ranges = room_ranges(pose, angles) + rng.normal(0, 0.01, 360)
        scan = Scan(ranges=ranges, angles=angles, range_min=0.12, range_max=3.5, stamp=0.2 * i)
        t0 = time.perf_counter()
        slam.step(pose, scan)
        times.append(time.perf_counter() - t0)
    h, w = slam.grid.shape
    maps_mb = slam.grid.nbytes / 2**20
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {"particles": particles, "beams": beams, "map_m": size, "cells": h * w,
            "median_ms": 1000 * float(np.median(times[3:])), "p95_ms": 1000 * float(np.percentile(times[3:], 95)),
            "maps_mb": maps_mb, "peak_rss_mb": peak_mb}


def baseline_rss_mb() -> float:
    """Peak RSS of an interpreter that loaded the core and ran the speed case's steps
    with one particle on a 1 m map: Python, numpy and the code, but no maps."""
    return float(in_own_process("bench.speed", 1, 60, 1.0)["peak_rss_mb"])


def speed_suite() -> list[dict]:
    base = baseline_rss_mb()
    rows = []
    print(f"{'N':>4} {'beams':>5} {'map':>5} {'ms/step':>8} {'p95':>7} {'maps MB':>8} "
          f"{'peak MB':>8} {'budget MB':>9}")
    for size in progress((10.0, 40.0), "map sizes"):
        for n in (20, 50, 100):
            for beams in (60, 360):
                row = in_own_process("bench.speed", n, beams, size)
                # The target: peak within 1.2 x the maps' own bytes plus the interpreter.
                row["budget_mb"] = 1.2 * row["maps_mb"] + base
                rows.append(row)
                print(f"{n:>4} {beams:>5} {size:>4.0f}m {row['median_ms']:>8.1f} {row['p95_ms']:>7.1f} "
                      f"{row['maps_mb']:>8.1f} {row['peak_rss_mb']:>8.1f} {row['budget_mb']:>9.1f}", flush=True)
    print(f"interpreter + core baseline: {base:.1f} MB")
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", help=argparse.SUPPRESS)  # one case, run by in_own_process
    args = parser.parse_args(argv)
    if args.case:
        n, beams, size = json.loads(args.case)
        print(json.dumps(speed_case(n, beams, size)))
        return 0
    speed_suite()
    return 0


if __name__ == "__main__":
    sys.exit(main())
