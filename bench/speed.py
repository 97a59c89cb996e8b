"""`make bench`: speed, memory and accuracy figures (recorded in docs/benchmarks.md).

    python -m bench.speed [speed] [intel] [office] [matcher] [longrun]    (default: all)

speed: for N in {20, 50, 100} and beams in {60, 360}, on a 10 m and a 40 m square map
at 0.05 m, the median milliseconds per full filter step and the peak memory of a fresh
process (each case in its own interpreter, so peak RSS is that case's alone).
intel, office: accuracy of the improved mode vs the assignment (fastslam.bench_accuracy).
matcher: the scan matcher alone against reference poses (fastslam.bench_matcher).
longrun: a 30-minute simulated run (office loop, faster than real time) with memory
and time per update sampled every 5 minutes of simulated time.
"""
from __future__ import annotations

import argparse
import functools
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

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
    maps_mb = slam.grid.logodds.nbytes / 2**20
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {"particles": particles, "beams": beams, "map_m": size, "cells": h * w,
            "median_ms": 1000 * float(np.median(times[3:])), "p95_ms": 1000 * float(np.percentile(times[3:], 95)),
            "maps_mb": maps_mb, "peak_rss_mb": peak_mb}


def baseline_rss_mb() -> float:
    """Peak RSS of an interpreter that loaded the core and ran the speed case's steps
    with one particle on a 1 m map: Python, numpy and the code, but no maps."""
    out = subprocess.run([sys.executable, "-m", "bench.speed", "--case", json.dumps([1, 60, 1.0])],
                         capture_output=True, text=True, check=True)
    return float(json.loads(out.stdout)["peak_rss_mb"])


def speed_suite() -> list[dict]:
    base = baseline_rss_mb()
    rows = []
    print(f"{'N':>4} {'beams':>5} {'map':>5} {'ms/step':>8} {'p95':>7} {'maps MB':>8} "
          f"{'peak MB':>8} {'budget MB':>9}")
    for size in (10.0, 40.0):
        for n in (20, 50, 100):
            for beams in (60, 360):
                out = subprocess.run([sys.executable, "-m", "bench.speed", "--case",
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


def current_rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize() / 2**20


def longrun_suite(minutes: float = 30.0, config: str = "config/slam.yaml") -> list[dict]:
    """Drives the office loop again and again for `minutes` of simulated time."""
    from pathlib import Path

    from fastslam.sim.route import load_route
    from fastslam.sim.sim import SimConfig, Simulation
    from fastslam.sim.world_loader import load_world

    root = Path(__file__).resolve().parents[1]
    world = load_world(root / "worlds" / "office.yaml")
    loop = load_route(root / "worlds" / "office.route.yaml")
    route = np.concatenate([loop] * 20)
    sim_cfg = SimConfig(seed=0)
    sim = Simulation(world, sim_cfg, np.random.default_rng(0), route=route)
    slam = FastSlam(SlamConfig.from_yaml(root / config, {"seed": 0}))
    angles = sim.lidar.angles
    rows, window, next_mark = [], [], 300.0
    start = time.perf_counter()
    print(f"{'sim min':>7} {'updates':>7} {'ms/update':>9} {'p95':>6} {'RSS MB':>7} {'maps MB':>8} {'grid':>9}")
    while sim.time < minutes * 60:
        tick = sim.step()
        if tick.scan is not None:
            scan = Scan.from_laser(tick.scan.astype(np.float32), float(angles[0]), float(angles[1] - angles[0]),
                                    sim_cfg.range_min, sim_cfg.range_max, mount=(sim_cfg.laser_x, 0.0, 0.0),
                                    stamp=tick.t)
            info = slam.step(sim.odom.pose.copy(), scan)
            window.append(info.seconds)
        if sim.time >= next_mark:
            next_mark += 300.0
            h, w = slam.grid.shape
            row = {"sim_min": round(sim.time / 60), "updates": slam.updates,
                   "ms_median": 1000 * float(np.median(window)), "ms_p95": 1000 * float(np.percentile(window, 95)),
                   "rss_mb": current_rss_mb(), "maps_mb": slam.grid.logodds.nbytes / 2**20, "grid": f"{h}x{w}"}
            rows.append(row)
            window = []
            print(f"{row['sim_min']:>7} {row['updates']:>7} {row['ms_median']:>9.1f} {row['ms_p95']:>6.1f} "
                  f"{row['rss_mb']:>7.1f} {row['maps_mb']:>8.1f} {row['grid']:>9}", flush=True)
        if tick.route_finished:
            break
    print(f"{minutes:.0f} simulated minutes in {time.perf_counter() - start:.0f} s wall")
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("suites", nargs="*", default=["speed", "intel", "office", "matcher", "longrun"],
                        help="speed, intel, office, matcher, longrun (default: all)")
    parser.add_argument("--case", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.case:
        n, beams, size = json.loads(args.case)
        print(json.dumps(speed_case(n, beams, size)))
        return 0
    for suite in args.suites:
        print(f"== {suite}", flush=True)
        if suite == "speed":
            speed_suite()
        elif suite == "intel":
            from bench.accuracy import intel_suite

            intel_suite()
        elif suite == "office":
            from bench.accuracy import office_suite

            office_suite()
        elif suite == "matcher":
            from bench.matcher import main as matcher_main

            for data in ("intel", "office"):
                matcher_main([data])
        elif suite == "longrun":
            longrun_suite()
        else:
            parser.error(f"unknown suite {suite!r}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
