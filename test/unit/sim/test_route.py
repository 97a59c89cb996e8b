"""The waypoint follower (pure), route parsing, and the shipped routes driven without ROS."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fastslam.sim.robot import integrate
from fastslam.sim.route import RouteFollower, load_route, parse_route
from fastslam.sim.sim import SimConfig, Simulation
from fastslam.sim.world import WorldError
from fastslam.sim.world_loader import load_world


def test_turns_in_place_then_drives() -> None:
    f = RouteFollower(np.array([[0.0, 1.0]]))
    v, w = f.command([0.0, 0.0, 0.0])       # target 90 deg left: turn only, at most the limit
    assert v == 0.0 and 0 < w <= 2.84
    v, w = f.command([0.0, 0.0, math.pi / 2])
    assert v == pytest.approx(0.22) and w == pytest.approx(0.0)


def test_reaches_waypoints_and_stops() -> None:
    f = RouteFollower(np.array([[1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]))
    pose = np.array([0.0, 0.0, 0.0])
    for _ in range(3000):
        v, w = f.command(pose)
        assert abs(v) <= 0.22 and abs(w) <= 2.84
        if f.done:
            break
        pose = integrate(pose, v, w, 1 / 60)
    assert f.done and f.command(pose) == (0.0, 0.0)
    assert math.hypot(pose[0] - 0.0, pose[1] - 1.0) < f.tolerance


def test_parse_route_forms_and_errors(tmp_path: Path) -> None:
    np.testing.assert_allclose(load_route("[[1, 2], [3, 4]]"), [[1, 2], [3, 4]])
    np.testing.assert_allclose(parse_route({"waypoints": [[0, 0, 90]]}), [[0, 0]])
    f = tmp_path / "r.yaml"
    f.write_text("waypoints:\n  - [1.5, 0]\n")
    np.testing.assert_allclose(load_route(str(f)), [[1.5, 0.0]])
    with pytest.raises(WorldError, match=r"waypoints\[1\]"):
        parse_route([[0, 0], [1, "a"]])
    with pytest.raises(WorldError, match="non-empty"):
        parse_route([])
    with pytest.raises(WorldError, match="cannot read"):
        load_route(str(tmp_path / "missing.yaml"))


@pytest.mark.parametrize("name, t_min, t_max", [("turtlebot3_world", 60, 120), ("room", 40, 150),
                                                ("office", 150, 400)])
def test_shipped_routes_are_collision_free(name: str, t_min: float, t_max: float, worlds_dir: Path) -> None:
    world = load_world(worlds_dir / f"{name}.yaml")
    sim = Simulation(world, SimConfig(range_noise=0.0), np.random.default_rng(0),
                     route=load_route(str(worlds_dir / f"{name}.route.yaml")))
    finished = False
    while not finished and sim.time < t_max:
        tick = sim.step()
        assert not sim.robot.collided, f"collision at t={sim.time:.1f} pose {sim.robot.pose}"
        finished = tick.route_finished
    assert finished and t_min <= sim.time <= t_max
    last = sim.route.waypoints[-1]
    assert math.hypot(*(sim.robot.pose[:2] - last)) < sim.route.tolerance


def test_the_long_building_route_is_collision_free_at_the_memory_benchs_speed(worlds_dir: Path) -> None:
    # bench/memory drives it at 1 m/s with 20 Hz physics: 246 m of corridor in about 250 s
    world = load_world(worlds_dir / "long_building.yaml")
    cfg = SimConfig(range_noise=0.0, max_linear=1.0, physics_rate=20.0, odom_rate=20.0, scan_rate=1.0)
    route = load_route(str(worlds_dir / "long_building.route.yaml"))
    sim = Simulation(world, cfg, np.random.default_rng(0), route=route)
    finished, lowest = False, math.inf
    while not finished and sim.time < 400:
        tick = sim.step()
        assert not sim.robot.collided, f"collision at t={sim.time:.1f} pose {sim.robot.pose}"
        lowest = min(lowest, float(world.clearance(sim.robot.pose[None, :2])[0]))
        finished = tick.route_finished
    assert finished and 246 <= sim.time <= 300 and lowest > 0.3
    assert math.hypot(*(sim.robot.pose[:2] - [248.0, 0.0])) < sim.route.tolerance
