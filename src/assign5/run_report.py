"""Watches a simulator run and writes its result: map files, picture, metrics.

Used by `make demo` (launch/demo.launch) and by the end-to-end rostest. It records the
ground truth, waits for the simulator's `route_done`, lets the SLAM node publish its
final map and trajectory, then evaluates them against the world.
"""
from __future__ import annotations

import json
import os
import threading
import time
from pathlib import Path as FilePath

import numpy as np
import rospy
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from nav_msgs.srv import GetMap
from std_msgs.msg import Bool, Float64

from fastslam.eval.maps import run_quality
from fastslam.eval.render import ESTIMATE_RGB, TRUTH_RGB, map_picture, write_png
from fastslam.geometry import relative, yaw_from_quaternion
from fastslam.io.map_files import save_map
from fastslam.sim.world_loader import load_world

from . import convert, params
from .params import ReportConfig


class RunRecorder:
    """Collects ground truth, the SLAM outputs and timing while a run goes on."""

    def __init__(self, slam_ns: str = "slam") -> None:
        # The map is fetched once at the end (dynamic_map service), not subscribed.
        self.lock = threading.Lock()
        self.path_arrived = threading.Condition(self.lock)
        self.truth: list[tuple[float, float, float, float]] = []
        self.update_ms: list[float] = []
        self.path: Path | None = None
        self.done = threading.Event()
        rospy.Subscriber("ground_truth", Odometry, self._on_truth, queue_size=100)
        rospy.Subscriber(f"{slam_ns}/update_time", Float64, self._on_time, queue_size=100)
        rospy.Subscriber(f"{slam_ns}/trajectory", Path, self._on_path, queue_size=1)
        rospy.Subscriber("route_done", Bool, self._on_done, queue_size=1)

    def _on_truth(self, msg: Odometry) -> None:
        pose = convert.odom_pose(msg)
        with self.lock:
            self.truth.append((msg.header.stamp.to_sec(), *pose))

    def _on_time(self, msg: Float64) -> None:
        with self.lock:
            self.update_ms.append(msg.data)

    def _on_path(self, msg: Path) -> None:
        with self.lock:
            self.path = msg
            self.path_arrived.notify_all()

    def _on_done(self, msg: Bool) -> None:
        if msg.data:
            self.done.set()

    def progress(self) -> str:
        with self.lock:
            truth = np.array(self.truth) if self.truth else np.zeros((0, 4))
            n, ms = len(self.update_ms), (np.mean(self.update_ms) if self.update_ms else 0.0)
        dist = float(np.sum(np.hypot(*np.diff(truth[:, 1:3], axis=0).T))) if len(truth) > 1 else 0.0
        sim_t = truth[-1, 0] - truth[0, 0] if len(truth) else 0.0
        return f"sim {sim_t:6.1f} s  driven {dist:5.1f} m  updates {n:5d}  {ms:5.1f} ms/update"

    def final_outputs(self, settle: float) -> tuple[np.ndarray, OccupancyGrid]:
        """The best particle's trajectory (T, 4) and map, after the node's next publication."""
        with self.lock:
            self.path = None
            self.path_arrived.wait_for(lambda: self.path is not None, timeout=settle)
        rospy.wait_for_service("dynamic_map", timeout=10.0)
        grid = rospy.ServiceProxy("dynamic_map", GetMap)().map
        with self.lock:
            path = self.path
        if path is None:
            raise RuntimeError("no trajectory published on ~trajectory")
        traj = np.array([(p.header.stamp.to_sec(), p.pose.position.x, p.pose.position.y,
                          yaw_from_quaternion(p.pose.orientation.x, p.pose.orientation.y,
                                              p.pose.orientation.z, p.pose.orientation.w))
                         for p in path.poses])
        return traj, grid


def evaluate(world_file: str, truth_world: np.ndarray, traj: np.ndarray, grid: OccupancyGrid,
             update_ms: list[float]) -> tuple[dict, np.ndarray, np.ndarray]:
    """Metrics of a run. The map frame is the odometry frame, whose origin is the
    robot's spawn pose in the world, so the truth is expressed relative to that pose."""
    world = load_world(world_file)
    truth = np.c_[truth_world[:, 0], relative(world.spawn, truth_world[:, 1:])]
    occ = np.asarray(grid.data, dtype=np.int8).reshape(grid.info.height, grid.info.width)
    origin = (grid.info.origin.position.x, grid.info.origin.position.y)
    metrics = {
        **run_quality(world, traj, truth, occ, grid.info.resolution, origin),
        "processed_scans": int(len(traj)),
        "ms_per_update_median": float(np.median(update_ms)) if update_ms else None,
        "ms_per_update_p95": float(np.percentile(update_ms, 95)) if update_ms else None,
    }
    return metrics, occ, truth


def write_outputs(out: FilePath, metrics: dict, occ: np.ndarray, grid: OccupancyGrid,
                  truth: np.ndarray, traj: np.ndarray) -> None:
    out.mkdir(parents=True, exist_ok=True)
    origin = (grid.info.origin.position.x, grid.info.origin.position.y, 0.0)
    save_map(str(out / "map"), occ, grid.info.resolution, origin)
    picture = map_picture(occ, grid.info.resolution, origin,
                          {"truth": (truth[:, 1:3], TRUTH_RGB), "estimate": (traj[:, 1:3], ESTIMATE_RGB)})
    write_png(out / "map.png", picture)
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2) + "\n")


def main() -> None:
    rospy.init_node("run_report")
    cfg = params.read(ReportConfig)
    out = FilePath(os.path.expanduser(cfg.out)).absolute()
    world_file, settle = cfg.world_file, cfg.settle
    print("waiting for the simulator's route; progress every 5 s", flush=True)
    rec = RunRecorder()
    last = 0.0
    while not rec.done.wait(0.2):
        if rospy.is_shutdown():
            return
        if time.monotonic() - last > 5.0:
            last = time.monotonic()
            print(rec.progress(), flush=True)
    print(rec.progress(), "- route done", flush=True)
    traj, grid = rec.final_outputs(settle)
    with rec.lock:
        truth_w, ms = np.array(rec.truth), list(rec.update_ms)
    metrics, occ, truth = evaluate(world_file, truth_w, traj, grid, ms)
    write_outputs(out, metrics, occ, grid, truth, traj)
    print(f"\nresults in {out}/: map.pgm map.yaml map.png metrics.json")
    for k, v in metrics.items():
        print(f"  {k:24s} {v:.3f}" if isinstance(v, float) else f"  {k:24s} {v}")
    rospy.signal_shutdown("run finished")
