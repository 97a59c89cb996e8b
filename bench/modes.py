"""The presets against each other: the Intel Research Lab log (`make bench intel`) and the
simulated office loop (`make bench office`). Each case runs a preset of config/ exactly as
a user gets it (only the seed set), so a row named `burger` measures config/burger.yaml.

The log's poses are the corrected trajectory; the filter gets odometry re-integrated
from them with the noise model of :mod:`fastslam.sim.odometry_noise` (level 1, seeded) and
every FLASER scan. For each configuration and seed it prints ATE (after the best
rigid 2D alignment) and RPE (consecutive processed scans) of the best particle's
trajectory, wall time, milliseconds per processed scan and the peak memory of the
process (each case runs in its own interpreter), plus a dead-reckoning row.

    python -m bench.modes [--seeds 0 1 2] [--level 1.0] [--configs real slam] [--office]

Intel: `real` (real data) and `slam` (the assignment). --office runs the simulated office
loop instead (office_suite: fastslam.simrun, no ROS, the LDS-01's 3.5 m range): `burger`
(the preset for that laser) and `slam`.
"""
from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

from bench.common import data_path, in_own_process, progress
from fastslam.config import SlamConfig
from fastslam.eval.trajectory import ate, rpe
from fastslam.filter.scan import Scan
from fastslam.filter.slam import FastSlam
from fastslam.io.carmen_log import read_log
from fastslam.sim.odometry_noise import noisy_odometry

ROOT = Path(__file__).resolve().parents[1]
# shared/ lies beside the repository (CI clones main next to it), /work/shared here
INTEL_LOG = data_path("intel-corrected.log.gz")
CONFIGS = {name: ROOT / "config" / f"{name}.yaml" for name in ("slam", "burger", "real")}
INTEL_CONFIGS = ("real", "slam")
OFFICE_CONFIGS = ("burger", "slam")


def intel_run(cfg: SlamConfig, seed: int, *, level: float = 1.0, log_path: Path = INTEL_LOG,
              limit: int | None = None) -> tuple[FastSlam, np.ndarray, np.ndarray, float, int]:
    """Runs cfg on the log; returns the filter, the matched reference (T, 3) and the
    estimate (T, 3) of the best particle, the wall time [s] and the scans processed."""
    log = read_log(log_path, limit=limit)
    truth = np.array([s.robot_pose for s in log.scans])
    odom = noisy_odometry(truth, level, np.random.default_rng(seed))
    slam = FastSlam(cfg)
    done: list[int] = []  # the log's stamps go backwards in places: match by index, not time
    start = time.perf_counter()
    for i, (rec, pose) in enumerate(zip(log.scans, odom)):
        scan = Scan.from_laser(rec.ranges.astype(np.float64), rec.angle_min, rec.angle_increment,
                               0.0, rec.max_range, mount=rec.mount, stamp=rec.t)
        if slam.step(pose, scan).processed:
            done.append(i)
    wall = time.perf_counter() - start
    return slam, truth[done], slam.trajectory()[:, 1:], wall, len(done)


def intel_case(name: str, seed: int, *, level: float = 1.0, log_path: Path = INTEL_LOG,
               limit: int | None = None) -> dict:
    """Runs one configuration on the log in this process and returns its figures."""
    cfg = SlamConfig.from_yaml(CONFIGS[name], {"seed": seed})
    _, ref, est, wall, processed = intel_run(cfg, seed, level=level, log_path=log_path, limit=limit)
    rpe_t, rpe_r = rpe(ref, est)
    return {"config": name, "seed": seed, "particles": cfg.particles, "ate_m": ate(ref, est),
            "rpe_m": rpe_t, "rpe_deg": rpe_r, "wall_s": wall, "ms_per_scan": 1000 * wall / max(processed, 1),
            "processed": processed, "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def dead_reckoning(seed: int, *, level: float = 1.0, log_path: Path = INTEL_LOG) -> dict:
    """The odometry alone as an estimate."""
    log = read_log(log_path)
    truth = np.array([s.robot_pose for s in log.scans])
    odom = noisy_odometry(truth, level, np.random.default_rng(seed))
    rpe_t, rpe_r = rpe(truth, odom)
    nan = float("nan")
    return {"config": "dead reckoning", "seed": seed, "particles": 0, "ate_m": ate(truth, odom),
            "rpe_m": rpe_t, "rpe_deg": rpe_r, "wall_s": nan, "ms_per_scan": nan, "processed": len(truth),
            "peak_mb": nan}


def _row(r: dict) -> str:
    return (f"{r['config']:<15} {r['seed']:>4} {r['particles']:>3} {r['ate_m']:>7.3f} {r['rpe_m']:>7.3f} "
            f"{r['rpe_deg']:>7.2f} {r['wall_s']:>7.1f} {r['ms_per_scan']:>7.1f} {r['peak_mb']:>7.0f}")


def intel_suite(seeds: tuple[int, ...] = (0, 1, 2), level: float = 1.0,
                configs: tuple[str, ...] = INTEL_CONFIGS) -> list[dict]:
    """Every configuration and seed in a fresh interpreter (one at a time); prints a table."""
    if not INTEL_LOG.exists():
        print(f"intel: {INTEL_LOG} not found, skipped")
        return []
    print(f"Intel Research Lab, {INTEL_LOG.name}, odometry noise level {level}")
    print(f"{'config':<15} {'seed':>4} {'N':>3} {'ATE m':>7} {'RPE m':>7} {'RPE deg':>7} "
          f"{'wall s':>7} {'ms/scan':>7} {'peak MB':>7}")
    rows = []
    for name in configs:
        for seed in progress(seeds, name):
            rows.append(in_own_process("bench.modes", "intel", name, seed, level))
            print(_row(rows[-1]), flush=True)
    for seed in seeds:
        rows.append(dead_reckoning(seed, level=level))
        print(_row(rows[-1]), flush=True)
    for name in configs:
        ates = [r["ate_m"] for r in rows if r["config"] == name]
        print(f"{name}: median ATE {np.median(ates):.3f} m over seeds {list(seeds)}")
    return rows


def office_case(name: str, seed: int, world: str = "office") -> dict:
    """One simulated run of the office route (fastslam.simrun, no ROS) and its figures."""
    from fastslam.simrun import run

    cfg = SlamConfig.from_yaml(CONFIGS[name], {"seed": seed})
    result = run(world, cfg, seed=seed)
    return {"config": name, "seed": seed, "particles": cfg.particles, **result.metrics(),
            "filter_s": result.seconds, "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def office_suite(seeds: tuple[int, ...] = (0, 1, 2),
                 configs: tuple[str, ...] = OFFICE_CONFIGS) -> list[dict]:
    """The office loop in the simulator for each configuration and seed; prints a table
    of the best particle's trajectory RMS error against the simulator's truth."""
    print("Simulated office loop (LDS-01 3.5 m, noisy odometry); filter s: time spent in the filter")
    print(f"{'config':<15} {'seed':>4} {'N':>3} {'RMS m':>7} {'max m':>7} {'odom m':>7} {'updates':>7} "
          f"{'ms/upd':>7} {'filter s':>8} {'peak MB':>7}")
    rows = []
    for name in configs:
        for seed in progress(seeds, name):
            r = in_own_process("bench.modes", "office", name, seed)
            rows.append(r)
            print(f"{name:<15} {seed:>4} {r['particles']:>3} {r['trajectory_rms_m']:>7.3f} "
                  f"{r['trajectory_max_m']:>7.3f} {r['dead_reckoning_rms_m']:>7.3f} {r['updates']:>7} "
                  f"{r['ms_per_update']:>7.1f} {r['filter_s']:>8.1f} {r['peak_mb']:>7.0f}", flush=True)
    for name in configs:
        rms = [r["trajectory_rms_m"] for r in rows if r["config"] == name]
        print(f"{name}: median trajectory RMS {np.median(rms):.3f} m over seeds {list(seeds)}")
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--level", type=float, default=1.0, help="odometry noise level")
    parser.add_argument("--configs", nargs="+", choices=sorted(CONFIGS),
                        help=f"presets (default: {' '.join(INTEL_CONFIGS)}; --office: {' '.join(OFFICE_CONFIGS)})")
    parser.add_argument("--office", action="store_true", help="the simulated office loop instead of Intel")
    parser.add_argument("--case", help=argparse.SUPPRESS)  # one case, run by in_own_process
    args = parser.parse_args(argv)
    if args.case:
        kind, *rest = json.loads(args.case)
        print(json.dumps(office_case(*rest) if kind == "office" else intel_case(*rest[:2], level=rest[2])))
        return 0
    if args.office:
        office_suite(tuple(args.seeds), tuple(args.configs or OFFICE_CONFIGS))
    else:
        intel_suite(tuple(args.seeds), args.level, tuple(args.configs or INTEL_CONFIGS))
    return 0


if __name__ == "__main__":
    sys.exit(main())
