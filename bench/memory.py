"""Peak memory of the filter on a 40 m and a 250 m explored area (`make bench memory`;
docs/benchmarks.md, "Maps").

    python -m bench.memory [--particles 30 100 300] [--areas intel building] [--dense]

intel: the Intel Research Lab log (about 40 m across, 910 scans), config/real.yaml,
odometry re-integrated with noise level 1, seed 0. building: worlds/long_building.yaml,
a 250 m long building driven along worlds/long_building.route.yaml by the simulator
(fastslam.simrun) with a 20 m laser, config/real.yaml, seed 0. Each case runs in its own
interpreter that imports only what it needs, so its peak RSS (ru_maxrss, interpreter
included) is its own; --dense keeps the maps as the dense (N, H, W) grids instead of
the shared tiles, for the figures beside them. The `import` rows are the interpreter with
the case's modules loaded and nothing run.
"""
from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path
from typing import Any, Iterator

ROOT = Path(__file__).resolve().parents[1]
PARTICLES = (30, 100, 300)
AREAS = ("intel", "building")
# The building's simulated robot and laser: a 20 m range (as real.yaml's max_range), 1 m/s.
BUILDING_SIM = {"range_max": 20.0, "num_beams": 360, "max_linear": 1.0, "physics_rate": 20.0,
                "odom_rate": 20.0, "scan_rate": 5.0}


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def memory_case(area: str, particles: int, dense: bool, run: bool = True) -> dict[str, Any]:
    """Runs one case in this process (run False: only its imports) and returns its figures."""
    import numpy as np

    from fastslam.config import SlamConfig
    from fastslam.filter.grid import GridMaps
    from fastslam.filter.slam import FastSlam

    if dense:
        FastSlam.maps_type = GridMaps
    cfg = SlamConfig.from_yaml(ROOT / "config" / "real.yaml", {"seed": 0, "particles": particles})
    if area == "intel":
        from bench.common import data_path
        from fastslam.filter.scan import Scan
        from fastslam.io.carmen_log import LaserRecord, iter_log, open_log
        from fastslam.sim.odometry_noise import noisy_odometry
    else:
        from fastslam.simrun import run as sim_run
    out: dict[str, Any] = {"area": area, "particles": particles, "maps": "dense" if dense else "tiles"}
    if not run:
        return {**out, "peak_rss_mb": _peak_mb()}
    cpu, start = _cpu_s(), time.perf_counter()
    if area == "intel":
        # the log streamed twice (poses for the odometry, then the scans), as a bag is read
        path = data_path("intel-corrected.log.gz")

        def scans() -> Iterator[LaserRecord]:
            with open_log(path) as f:
                yield from (item for item in iter_log(f) if isinstance(item, LaserRecord))

        odom = noisy_odometry(np.array([rec.robot_pose for rec in scans()]), 1.0, np.random.default_rng(0))
        slam = FastSlam(cfg)
        for rec, pose in zip(scans(), odom):
            slam.step(pose, Scan.from_laser(rec.ranges.astype(np.float64), rec.angle_min, rec.angle_increment, 0.0,
                                            rec.max_range, mount=rec.mount, stamp=rec.t))
    else:
        slam = sim_run(str(ROOT / "worlds" / "long_building.yaml"), cfg, sim=BUILDING_SIM, seed=0,
                       max_time=3600.0).slam
    grid = slam.grid
    h, w = grid.shape
    pool = getattr(grid, "pool", None)
    return {**out, "peak_rss_mb": _peak_mb(), "maps_mb": grid.nbytes / 2**20,
            "tiles_used": pool.used if pool is not None else 0,
            "extent_m": f"{w * grid.resolution:.0f} x {h * grid.resolution:.0f}", "updates": slam.updates,
            "cpu_s": _cpu_s() - cpu, "wall_s": time.perf_counter() - start}


def memory_suite(particles: tuple[int, ...] = PARTICLES, areas: tuple[str, ...] = AREAS,
                 dense: bool = False) -> list[dict[str, Any]]:
    """Every case in its own interpreter, one at a time; prints a table."""
    from bench.common import in_own_process

    kinds = [False, True] if dense else [False]
    print(f"{'area':<9} {'N':>4} {'maps':<6} {'peak MB':>8} {'maps MB':>8} {'tiles':>7} {'grid m':>10} "
          f"{'updates':>7} {'cpu s':>7}")
    rows = []
    for area in areas:
        base = in_own_process("bench.memory", area, particles[0], False, False)
        print(f"{area:<9} {'':>4} {'import':<6} {base['peak_rss_mb']:>8.1f}", flush=True)
        for n in particles:
            for kind in kinds:
                r = in_own_process("bench.memory", area, n, kind, True)
                rows.append(r)
                print(f"{area:<9} {n:>4} {r['maps']:<6} {r['peak_rss_mb']:>8.1f} {r['maps_mb']:>8.1f} "
                      f"{r['tiles_used']:>7} {r['extent_m']:>10} {r['updates']:>7} {r['cpu_s']:>7.1f}", flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=int, nargs="+", default=list(PARTICLES))
    parser.add_argument("--areas", nargs="+", default=list(AREAS), choices=AREAS)
    parser.add_argument("--dense", action="store_true", help="the dense grids too, beside the tiles")
    parser.add_argument("--case", help=argparse.SUPPRESS)  # one case, run by in_own_process
    args = parser.parse_args(argv)
    if args.case:
        print(json.dumps(memory_case(*json.loads(args.case))))
        return 0
    memory_suite(tuple(args.particles), tuple(args.areas), args.dense)
    return 0


if __name__ == "__main__":
    sys.exit(main())
