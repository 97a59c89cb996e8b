"""CARMEN log -> ROS 1 bag (/scan, /odom, /tf, /tf_static) plus the reference trajectory.

One odometry message (and one odom -> base_link tf) is written per scan, at the scan's
logger timestamp. The odometry is the log's robot pose re-integrated with the noise
model of :mod:`fastslam.sim.odometry_noise` (level 0 = the log's poses); the log's poses
themselves go to ``<bag>.gt.txt`` as the reference trajectory, the odometry to
``<bag>.odom.txt``.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from fastslam.geometry import relative
from fastslam.io.bag_reader import OdomRecord, ScanRecord
from fastslam.io.bag_writer import BagWriter
from fastslam.io.carmen_log import CarmenLog
from fastslam.sim.odometry_noise import DEFAULT_ALPHAS, OdomNoise, noisy_odometry
from fastslam.io.trajectory_files import write_trajectory
from fastslam.transforms import StaticTransform


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


def log_trajectory(log: CarmenLog) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """((T,) strictly increasing scan times [s], (T, 3) robot poses) of the log's laser scans."""
    times = increasing_times(np.array([s.t for s in log.scans], dtype=np.float64))
    poses = np.array([s.robot_pose for s in log.scans], dtype=np.float64).reshape(-1, 3)
    return times, poses


def log_mount(log: CarmenLog) -> tuple[float, float, float]:
    """Laser pose on the robot (x, y, yaw): from ROBOTLASER1's two poses, else the
    FLASER front-laser offset PARAM (0 when not logged)."""
    for s in log.scans:
        if s.kind == "ROBOTLASER1":
            m = relative(s.robot_pose, s.laser_pose)
            return float(m[0]), float(m[1]), float(m[2])
    return log.front_laser_offset, 0.0, 0.0


def convert(log: CarmenLog, out: str | os.PathLike[str], *, odom_noise: float = 0.0, seed: int = 0,
            alphas: OdomNoise = DEFAULT_ALPHAS, odom_frame: str = "odom", base_frame: str = "base_link",
            laser_frame: str = "laser") -> Conversion:
    """Write ``out`` (a new bag), ``out.gt.txt`` and ``out.odom.txt`` from a parsed log.

    Args:
        log: the parsed CARMEN log (at least one laser scan).
        out: bag path; must not exist.
        odom_noise: noise level of the re-integrated odometry (0 = exact).
        seed: seed of the odometry noise; the same (level, seed) gives the same bag.
    """
    if not log.scans:
        raise ValueError("the log has no FLASER or ROBOTLASER1 scans")
    times, truth = log_trajectory(log)
    odometry = noisy_odometry(truth, odom_noise, np.random.default_rng(seed), alphas)
    mount = log_mount(log)
    out = Path(out)
    with BagWriter(out) as writer:
        writer.static([StaticTransform.planar(base_frame, laser_frame, *mount)], t=float(times[0]))
        for s, t, (x, y, yaw) in zip(log.scans, times.tolist(), odometry.tolist()):
            writer.odom(OdomRecord(t, x, y, yaw, child_frame_id=base_frame, frame_id=odom_frame))
            writer.scan(ScanRecord(t, s.ranges, s.angle_min, s.angle_increment, 0.0, s.max_range,
                                   frame_id=laser_frame))
    comment = (f"reference trajectory (the log's robot poses) for {out.name}\n"
               f"odometry noise level {odom_noise} seed {seed} coefficients {alphas._asdict()}")
    ref = write_trajectory(reference_path(out), times, truth, comment=comment)
    # the odometry as a trajectory too, so dead reckoning can be scored with fastslam.evaluate
    write_trajectory(reference_path(out, "odom"), times, odometry, comment=f"odometry in {out.name}\n{comment}")
    return Conversion(bag=out, reference=ref, scans=len(times), mount=mount, times=times,
                      truth=truth, odometry=odometry)
