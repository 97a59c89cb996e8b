"""A whole simulated run without ROS: the simulator feeds the filter directly.

The same physics as the simulator node and the same FastSlam.step as slam.py, so tests,
benchmarks and parameter studies run in seconds. The map frame is the odometry frame,
which starts at the spawn pose; the truth is expressed in it for evaluation.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping

import numpy as np

from fastslam.config import SlamConfig
from fastslam.eval.maps import run_quality, trajectory_errors
from fastslam.filter.frontend import Dropped, Frontend
from fastslam.filter.scan import Scan
from fastslam.filter.scan_wait import ScanWait
from fastslam.filter.slam import FastSlam, StepInfo
from fastslam.geometry import relative
from fastslam.io.records import OdomRecord, ScanRecord
from fastslam.sim.route import load_route
from fastslam.sim.sim import SimConfig, Simulation
from fastslam.sim.world import World
from fastslam.sim.world_loader import load_world

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


WORLDS = Path(__file__).resolve().parents[2] / "worlds"


@dataclass
class SimRun:
    slam: FastSlam
    world: World
    truth: NDArray[np.float64]  # (T, 4) t, x, y, theta of every odometry tick, map frame
    odom: NDArray[np.float64]   # (T, 4) the odometry the filter saw, odom (= map) frame
    seconds: float          # wall time spent in FastSlam.step
    updates: int
    dropped: int = 0        # scans the Frontend refused
    mount: tuple[float, float, float] = (0.0, 0.0, 0.0)  # the laser in the base frame (x, y, yaw)
    scans: list[ScanRecord] = field(default_factory=list)   # every scan, when recorded
    odoms: list[OdomRecord] = field(default_factory=list)   # every odometry tick, when recorded

    def metrics(self) -> dict[str, Any]:
        grid = self.slam.grid
        dr = trajectory_errors(self.odom, self.truth)
        return {
            **run_quality(self.world, self.slam.trajectory(), self.truth, self.slam.best_occupancy(),
                          grid.resolution, tuple(grid.origin)),
            "dead_reckoning_rms_m": float(np.sqrt(np.mean(dr ** 2))),
            "updates": self.updates,
            "ms_per_update": 1000.0 * self.seconds / max(self.updates, 1),
        }


def world_path(name: str) -> Path:
    p = Path(name)
    return p if p.suffix in (".yaml", ".yml") and p.exists() else WORLDS / f"{name}.yaml"


def run(world: str, slam_cfg: SlamConfig, *, route: str | NDArray[np.float64] | None = None,
        sim: Mapping[str, Any] | None = None, seed: int = 0, max_time: float = 1200.0, record: bool = False,
        on_update: Callable[[Simulation, FastSlam, StepInfo], None] | None = None) -> SimRun:
    """Drives a route (default worlds/<world>.route.yaml) to its end, feeding every
    odometry tick and scan through the Frontend, as the node and the offline tool do.

    Args:
        route: a waypoint file, or the waypoints (K, 2) themselves.
        sim: SimConfig overrides (e.g. {"odom_noise": False}).
        seed: the simulator's noise seed (the filter has its own, in slam_cfg).
        record: keep every scan and odometry message, to write a bag from.
        on_update: called after every processed scan (e.g. to sample memory and time).
    """
    w = load_world(world_path(world))
    if isinstance(route, np.ndarray):
        waypoints = route
    else:
        waypoints = load_route(Path(route) if route else WORLDS / f"{Path(world).stem}.route.yaml")
    sim_cfg = SimConfig.from_dict({**(sim or {}), "seed": seed})
    simulation = Simulation(w, sim_cfg, np.random.default_rng(seed), route=waypoints)
    slam = FastSlam(slam_cfg)
    front = Frontend(slam)
    lidar = simulation.lidar
    mount = lidar.mount
    truth, odom, scans, odoms = [], [], [], []
    spent, updates, dropped = 0.0, 0, 0
    angle_min, increment = float(lidar.angles[0]), float(lidar.angles[1] - lidar.angles[0])
    # a scan between two odometry ticks waits for the next, as in the node (scan_wait.py)
    waits: ScanWait[Scan] = ScanWait()

    def handle(scan: Scan) -> None:
        nonlocal spent, updates, dropped
        start = time.perf_counter()
        info: StepInfo | None = None
        try:
            info = front.add_scan(scan)
        except Dropped:
            dropped += 1
        spent += time.perf_counter() - start
        front.events.clear()  # the simulator's streams are clean: nothing to report
        if info is not None and info.processed:
            updates += 1
            if on_update is not None:
                on_update(simulation, slam, info)

    while simulation.time < max_time:
        tick = simulation.step()
        for held in waits.due(tick.t):
            handle(held)
        if tick.odom_due:
            truth.append((tick.t, *relative(w.spawn, simulation.robot.pose)))
            odom.append((tick.t, *simulation.odom.pose))
            front.add_odom(tick.t, simulation.odom.pose.copy())
            if record:
                x, y, yaw = simulation.odom.pose
                odoms.append(OdomRecord(tick.t, x, y, yaw, child_frame_id="base_footprint"))
            for held in waits.odometry(tick.t):
                handle(held)
        if tick.scan is not None:
            ranges = tick.scan.astype(np.float32)  # as a LaserScan message carries them
            if record:
                scans.append(ScanRecord(tick.t, ranges, angle_min, increment, sim_cfg.range_min,
                                        sim_cfg.range_max, frame_id="base_scan"))
            scan = Scan.from_laser(ranges, angle_min, increment, sim_cfg.range_min, sim_cfg.range_max,
                                   mount=mount, stamp=tick.t)
            for ready in waits.scan(tick.t, scan):
                handle(ready)
        if tick.route_finished:
            break
    for held in waits.rest():
        handle(held)
    return SimRun(slam=slam, world=w, truth=np.array(truth), odom=np.array(odom), seconds=spent,
                  updates=updates, dropped=dropped, mount=mount, scans=scans, odoms=odoms)
