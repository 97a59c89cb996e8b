"""Convert a CARMEN log into a ROS 1 bag for the offline SLAM.

    python -m fastslam.carmen_to_bag LOG --out BAG [--odom-noise LEVEL --seed N] [--max-range R] [--limit K]

Writes BAG (/scan, /odom, /tf, /tf_static), BAG.gt.txt (the log's poses, ``t x y
theta``) and BAG.odom.txt (the odometry). The odometry re-integrates the logged
motion with the noise model of :mod:`fastslam.sim.odometry_noise` scaled by LEVEL
(0 = the logged poses).
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from fastslam.io.bag_reader import BagError
from fastslam.io.carmen_log import CarmenError, read_log
from fastslam.io.carmen_bag import convert
from fastslam.eval.trajectory import ate


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m fastslam.carmen_to_bag", description=__doc__.split("\n")[0])
    ap.add_argument("log", help="CARMEN log, plain or gzip")
    ap.add_argument("--out", required=True, help="bag to create (must not exist)")
    ap.add_argument("--odom-noise", type=float, default=0.0, metavar="LEVEL",
                    help="odometry noise multiplier (0 = exact, 1 = the documented model)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the odometry noise")
    ap.add_argument("--max-range", type=float, default=None, metavar="R",
                    help="readings >= R [m] are no returns (FLASER default 81.83)")
    ap.add_argument("--limit", type=int, default=None, help="convert only the first K scans")
    args = ap.parse_args(argv)
    try:
        log = read_log(args.log, max_range=args.max_range, limit=args.limit)
        result = convert(log, args.out, odom_noise=args.odom_noise, seed=args.seed)
    except (OSError, CarmenError, BagError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    duration = float(result.times[-1] - result.times[0]) if result.scans > 1 else 0.0
    drift = ate(result.truth, result.odometry)
    end = float(np.hypot(*(result.truth[-1, :2] - result.odometry[-1, :2])))
    print(f"{result.scans} scans over {duration:.1f} s -> {result.bag}\n"
          f"reference trajectory -> {result.reference}\n"
          f"laser mount (x, y, yaw) = {result.mount}\n"
          f"odometry noise level {args.odom_noise} seed {args.seed}: "
          f"dead-reckoning ATE {drift:.3f} m, final position error {end:.3f} m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
