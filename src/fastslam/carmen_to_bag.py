"""Convert a CARMEN log into a ROS 1 bag for the offline SLAM.

    python -m fastslam.carmen_to_bag LOG --out BAG [--odom-noise LEVEL --seed N] [--max-range R] [--limit K]
                                     [--format tum] [--quiet]

Writes BAG (/scan, /odom, /tf, /tf_static), BAG.gt.txt (the log's poses) and
BAG.odom.txt (the odometry), as ``t x y theta`` or, with --format tum, TUM's
``t x y z qx qy qz qw`` (what evo reads). The odometry re-integrates the logged
motion with the noise model of :mod:`fastslam.sim.odometry_noise` scaled by LEVEL
(0 = the logged poses).
"""
from __future__ import annotations

import argparse
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from tqdm import tqdm

from fastslam.cli import closed_output_ends_quietly
from fastslam.eval.trajectory import ate
from fastslam.io.bag_writer import BagWriter
from fastslam.io.carmen_log import CarmenError, CarmenLog, read_log
from fastslam.io.records import BagError, OdomRecord, ScanRecord
from fastslam.io.staging import staged
from fastslam.io.trajectory_files import FORMATS, write_trajectory
from fastslam.sim.odometry_noise import DEFAULT_ALPHAS, OdomNoise, noisy_odometry
from fastslam.transforms import StaticTransform

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


@dataclass(frozen=True)
class Conversion:
    """What was written: paths, counts, the laser mounting and both trajectories (T, 3)."""

    bag: Path
    reference: Path
    scans: int
    mount: tuple[float, float, float]
    times: NDArray[np.float64]
    truth: NDArray[np.float64]
    odometry: NDArray[np.float64]


def reference_path(bag: str | os.PathLike[str], kind: str = "gt") -> Path:
    """``out.bag`` -> ``out.bag.gt.txt`` (or ``out.bag.odom.txt`` for kind "odom")."""
    bag = Path(bag)
    return bag.with_name(f"{bag.name}.{kind}.txt")


MIN_DT = 1e-3  # [s] spacing forced between scans whose logged times do not increase


def increasing_times(times: NDArray[np.float64], min_dt: float = MIN_DT) -> NDArray[np.float64]:
    """Clamp each time to at least the previous one + ``min_dt`` (file order is kept).

    The Intel log's logger timestamps go backwards 4 times (by up to 0.86 s) while the
    poses stay continuous in file order, so the file order is the motion order; bag
    readers sort by time, hence the bag must not reorder those scans.
    """
    t = np.asarray(times, dtype=np.float64)
    k = np.arange(len(t)) * min_dt
    return np.maximum.accumulate(t - k) + k


UNTIMED_DT = 1.0  # [s] between the scans of a log without timestamps (orebro's are all 0)


def untimed(log: CarmenLog) -> bool:
    """Whether every scan of the log carries the same time (no timing at all)."""
    return len(log.scans) > 1 and len({s.t for s in log.scans}) == 1


def log_trajectory(log: CarmenLog) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """((T,) strictly increasing scan times [s], (T, 3) robot poses) of the log's laser scans.

    A log without timestamps gets one scan every UNTIMED_DT from UNTIMED_DT on: 1 ms apart
    its 1-3 m steps looked like 1000 m/s to the odometry's speed rule, and a scan stamped 0
    is one ROS calls unstamped (the first was dropped).
    """
    if untimed(log):
        times = UNTIMED_DT * np.arange(1, len(log.scans) + 1, dtype=np.float64)
    else:
        times = increasing_times(np.array([s.t for s in log.scans], dtype=np.float64))
    poses = np.array([s.robot_pose for s in log.scans], dtype=np.float64).reshape(-1, 3)
    return times, poses


def convert(log: CarmenLog, out: str | os.PathLike[str], *, odom_noise: float = 0.0, seed: int = 0,
            alphas: OdomNoise = DEFAULT_ALPHAS, odom_frame: str = "odom", base_frame: str = "base_link",
            laser_frame: str = "laser", fmt: str = "xytheta", progress: bool = False) -> Conversion:
    """Write ``out`` (a new bag), ``out.gt.txt`` and ``out.odom.txt`` from a parsed log.

    Args:
        log: the parsed CARMEN log (at least one laser scan).
        out: bag path; must not exist.
        odom_noise: noise level of the re-integrated odometry (0 = exact).
        seed: seed of the odometry noise; the same (level, seed) gives the same bag.
        fmt: the trajectories' format, "xytheta" or "tum".
        progress: a progress bar (tqdm) on stderr.
    """
    if not log.scans:
        raise ValueError("the log has no FLASER or ROBOTLASER1 scans")
    times, truth = log_trajectory(log)
    odometry = noisy_odometry(truth, odom_noise, np.random.default_rng(seed), alphas)
    mount = log.laser_mount()
    out = Path(out)
    if out.exists():
        raise BagError(f"{out} exists; choose a new name")
    comment = (f"reference trajectory (the log's robot poses) for {out.name}\n"
               f"odometry noise level {odom_noise} seed {seed} coefficients {alphas._asdict()}")
    # Written under temporary names, renamed when all three are complete (the bag last):
    # an error or a kill leaves no half-written bag behind.
    with staged(reference_path(out), reference_path(out, "odom"), out) as (gt_tmp, odom_tmp, bag_tmp):
        with BagWriter(bag_tmp) as writer:
            writer.static([StaticTransform.planar(base_frame, laser_frame, *mount)], t=float(times[0]))
            rows = zip(log.scans, times.tolist(), odometry.tolist())
            for s, t, (x, y, yaw) in tqdm(rows, total=len(times), unit="scan", disable=not progress,
                                          file=sys.stderr, mininterval=0.5):
                writer.odom(OdomRecord(t, x, y, yaw, child_frame_id=base_frame, frame_id=odom_frame))
                writer.scan(ScanRecord(t, s.ranges, s.angle_min, s.angle_increment, 0.0, s.max_range,
                                       frame_id=laser_frame))
        write_trajectory(gt_tmp, times, truth, comment=comment, fmt=fmt)
        # the odometry as a trajectory too, so dead reckoning can be scored with fastslam.evaluate
        write_trajectory(odom_tmp, times, odometry, comment=f"odometry in {out.name}\n{comment}", fmt=fmt)
    return Conversion(bag=out, reference=reference_path(out), scans=len(times), mount=mount, times=times,
                      truth=truth, odometry=odometry)


@closed_output_ends_quietly
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
    ap.add_argument("--format", choices=FORMATS, default="xytheta",
                    help="reference and odometry trajectories: t x y theta (default) or TUM's t x y z qx qy qz qw")
    ap.add_argument("--quiet", action="store_true", help="no progress bar (there is none off a terminal)")
    args = ap.parse_args(argv)
    try:
        log = read_log(args.log, max_range=args.max_range, limit=args.limit)
        result = convert(log, args.out, odom_noise=args.odom_noise, seed=args.seed, fmt=args.format,
                         progress=not args.quiet and sys.stderr.isatty())
    except (OSError, CarmenError, BagError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted: nothing written", file=sys.stderr)
        return 130
    except Exception as err:  # the bag library's own errors: one line, never a traceback
        print(f"error: writing {args.out} failed: {type(err).__name__}: {err}", file=sys.stderr)
        return 1
    if untimed(log):
        print(f"warning: the log's scans carry no timestamps (all {log.scans[0].t:g} s): stamped "
              f"{UNTIMED_DT:g} s apart in file order", file=sys.stderr)
    if log.saturation is not None:
        nothing = sum(int(np.count_nonzero(~np.isfinite(sc.ranges))) for sc in log.scans)
        print(f"notice: the laser saturates at {log.saturation:.1f} m (a band of readings there and hardly any "
              f"beyond): readings from {log.saturation:.1f} m on are no returns ({nothing} in all); "
              "--max-range sets the limit by hand", file=sys.stderr)
    if log.skipped:
        print(f"warning: {len(log.skipped)} ODOM line(s) left out (not needed: the odometry is re-integrated "
              f"from the scans' poses); first: {log.skipped[0]}", file=sys.stderr)
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
