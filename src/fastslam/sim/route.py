"""Scripted driving: a waypoint follower (turn toward the next point, then drive).

Pure functions of the pose: no time, no ROS. The robot turns in place while the
heading error is large, so it follows the straight lines between waypoints closely
and a route drawn with clearance stays collision-free.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from fastslam.geometry import wrap_angle
from fastslam.sim.robot import MAX_ANGULAR, MAX_LINEAR
from fastslam.sim.world import WorldError

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import ArrayLike, NDArray


def parse_route(data: Any, where: str = "route") -> NDArray[np.float64]:
    """Parsed YAML (a list of [x, y] or a mapping with ``waypoints``) -> waypoints (W, 2), world frame."""
    if isinstance(data, dict):
        if "waypoints" not in data:
            raise WorldError(f"{where}: a route mapping needs a 'waypoints' list")
        data = data["waypoints"]
    if not isinstance(data, list) or not data:
        raise WorldError(f"{where}: expected a non-empty list of [x, y] waypoints, got {data!r}")
    pts = []
    for i, p in enumerate(data):
        if (not isinstance(p, (list, tuple)) or len(p) not in (2, 3)
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in p)):
            raise WorldError(f"{where}.waypoints[{i}]: expected [x, y] numbers, got {p!r}")
        pts.append([float(p[0]), float(p[1])])
    return np.asarray(pts, dtype=float)


def load_route(text_or_path: str | Path) -> NDArray[np.float64]:
    """Waypoints (W, 2) from a route file path, or from inline YAML such as ``[[1, 0], [1, 1]]``."""
    text = str(text_or_path).strip()
    path = Path(text).expanduser()
    if not text.lstrip().startswith(("[", "{")) and path.suffix in (".yaml", ".yml"):
        try:
            return parse_route(yaml.safe_load(path.read_text()), path.name)
        except OSError as err:
            raise WorldError(f"route: cannot read {path}: {err.strerror}") from None
        except yaml.YAMLError as err:
            raise WorldError(f"route: {path.name} is not valid YAML: {err}") from None
    try:
        return parse_route(yaml.safe_load(text))
    except yaml.YAMLError as err:
        raise WorldError(f"route: not a file and not valid inline YAML: {err}") from None


@dataclass
class RouteFollower:
    """Turn-then-drive controller over waypoints (W, 2); ``command(pose)`` -> (v, w)."""

    waypoints: NDArray[np.float64]
    tolerance: float = 0.08           # [m] a waypoint closer than this is reached
    max_linear: float = MAX_LINEAR    # [m/s]
    max_angular: float = MAX_ANGULAR  # [rad/s]
    turn_gain: float = 2.5            # [1/s] w = gain * heading error
    drive_below: float = 0.35         # [rad] drive only when the heading error is below this
    index: int = 0

    @property
    def done(self) -> bool:
        return self.index >= len(self.waypoints)

    def command(self, pose: ArrayLike) -> tuple[float, float]:
        """Velocity command (v [m/s], w [rad/s]) for the robot at pose (3,) (world frame); (0, 0) when done."""
        x, y, th = (float(v) for v in np.asarray(pose, dtype=float))
        while not self.done and math.hypot(self.waypoints[self.index, 0] - x,
                                           self.waypoints[self.index, 1] - y) < self.tolerance:
            self.index += 1
        if self.done:
            return 0.0, 0.0
        tx, ty = self.waypoints[self.index]
        dist = math.hypot(tx - x, ty - y)
        err = float(wrap_angle(math.atan2(ty - y, tx - x) - th))
        w = max(-self.max_angular, min(self.max_angular, self.turn_gain * err))
        if abs(err) > self.drive_below:
            return 0.0, w
        # slow down over the last 0.3 m of the final leg so the robot stops on the point
        last = self.index == len(self.waypoints) - 1
        v = self.max_linear * math.cos(err) * (min(1.0, dist / 0.3 + 0.2) if last else 1.0)
        return min(self.max_linear, v), w
