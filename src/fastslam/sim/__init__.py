"""ROS-free TurtleBot3 burger simulator: worlds, exact lidar, diff-drive, routes (numpy only)."""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

from fastslam.sim.lidar import Lidar, cast_rays, ray_circles, ray_segments
from fastslam.sim.robot import MAX_ANGULAR, MAX_LINEAR, RADIUS, DiffDrive, OdometryModel, clamp_cmd, integrate
from fastslam.sim.route import RouteFollower, load_route, parse_route
from fastslam.sim.sim import SimConfig, Simulation, Tick
from fastslam.sim.world import World, WorldError, regular_polygon, world_from_dict

if TYPE_CHECKING:
    from fastslam.sim.world_loader import load_world

__all__ = ["Lidar", "cast_rays", "ray_circles", "ray_segments", "MAX_ANGULAR", "MAX_LINEAR", "RADIUS",
           "DiffDrive", "OdometryModel", "clamp_cmd", "integrate", "RouteFollower", "load_route",
           "parse_route", "SimConfig", "Simulation", "Tick", "World", "WorldError", "load_world",
           "regular_polygon", "world_from_dict"]


def __getattr__(name: str) -> Any:
    """load_world on first use: its map_server loader imports Pillow (5 MB), which the
    other modules of the package (the noise model of the offline benches) do not need."""
    if name == "load_world":
        from fastslam.sim.world_loader import load_world
        return load_world
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
