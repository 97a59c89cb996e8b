"""`make bench`: speed and memory of one full filter step, on synthetic scans.

For N in {20, 50, 100} and beams in {60, 360}, on a 10 m and a 40 m square map at
0.05 m, it prints the median milliseconds per step and the peak memory of a fresh
process (the maps dominate it). Each case runs in its own interpreter so peak RSS
belongs to that case alone. Other suites (datasets, accuracy) are added by name:
`python -m fastslam.bench [speed] [...]`.
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time

import numpy as np

from .config import SlamConfig
from .scan import Scan
from .slam import FastSlam


def room_ranges(pose: np.ndarray, angles: np.ndarray, half: float = 2.5) -> np.ndarray:
    """Analytic ranges from pose (3,) inside a square room of half-width `half`, with a pillar."""
    a = pose[2] + angles
    c, s = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(c > 0, (half - pose[0]) / c, np.where(c < 0, (-half - pose[0]) / c, np.inf))
        ty = np.where(s > 0, (half - pose[1]) / s, np.where(s < 0, (-half - pose[1]) / s, np.inf))
        # pillar of radius 0.3 at (1, 1)
        px, py = 1.0 - pose[0], 1.0 - pose[1]
        b = px * c + py * s
        disc = b * b - (px * px + py * py - 0.09)
        tp = np.where((disc >= 0) & (b > 0), b - np.sqrt(np.maximum(disc, 0)), np.inf)
    return np.minimum(np.minimum(tx, ty), tp)


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
    maps_mb = slam.grid.logodds.nbytes / 2**20
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {"particles": particles, "beams": beams, "map_m": size, "cells": h * w,
            "median_ms": 1000 * float(np.median(times[3:])), "p95_ms": 1000 * float(np.percentile(times[3:], 95)),
            "maps_mb": maps_mb, "peak_rss_mb": peak_mb}


def baseline_rss_mb() -> float:
    """Peak RSS of an interpreter that imported the core and did nothing else."""
    out = subprocess.run([sys.executable, "-c", "import resource, fastslam.slam; "
                          "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)"],
                         capture_output=True, text=True, check=True)
    return float(out.stdout)


def speed_suite() -> list[dict]:
    base = baseline_rss_mb()
    rows = []
    print(f"{'N':>4} {'beams':>5} {'map':>5} {'ms/step':>8} {'p95':>7} {'maps MB':>8} "
          f"{'peak MB':>8} {'budget MB':>9}")
    for size in (10.0, 40.0):
        for n in (20, 50, 100):
            for beams in (60, 360):
                out = subprocess.run([sys.executable, "-m", "fastslam.bench", "--case",
                                      json.dumps([n, beams, size])],
                                     capture_output=True, text=True, check=True)
                row = json.loads(out.stdout)
                # The target: peak within 1.2 x the maps' own bytes plus the interpreter.
                row["budget_mb"] = 1.2 * row["maps_mb"] + base
                rows.append(row)
                print(f"{n:>4} {beams:>5} {size:>4.0f}m {row['median_ms']:>8.1f} {row['p95_ms']:>7.1f} "
                      f"{row['maps_mb']:>8.1f} {row['peak_rss_mb']:>8.1f} {row['budget_mb']:>9.1f}", flush=True)
    print(f"interpreter + core baseline: {base:.1f} MB")
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("suites", nargs="*", default=["speed"], help="speed (default)")
    parser.add_argument("--case", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.case:
        n, beams, size = json.loads(args.case)
        print(json.dumps(speed_case(n, beams, size)))
        return 0
    for suite in args.suites:
        if suite == "speed":
            speed_suite()
        else:
            parser.error(f"unknown suite {suite!r}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
