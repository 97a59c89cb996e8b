"""The simulator's clockwork: fixed ticks, sensor rates, the cmd_vel timeout, its configuration."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastslam.config import ConfigError
from fastslam.geometry import relative
from fastslam.sim.sim import SimConfig, Simulation
from fastslam.sim.world import world_from_dict


def test_simulation_clock_rates_and_cmd_timeout() -> None:
    world = world_from_dict({"circles": [[50, 50, 1]]})
    sim = Simulation(world, SimConfig(odom_noise=False), np.random.default_rng(0))
    sim.set_cmd(0.1, 0.0)
    ticks = [sim.step() for _ in range(180)]              # 3 s at 60 Hz
    assert sim.time == pytest.approx(3.0)
    assert sum(t.scan is not None for t in ticks) == 15   # 5 Hz
    assert sum(t.odom_due for t in ticks) == 90           # 30 Hz
    # the command stopped after cmd_vel_timeout = 1 s (like turtlebot3_fake)
    np.testing.assert_allclose(sim.robot.pose[0], 0.1 * 1.0, atol=0.1 / 60 + 1e-9)
    np.testing.assert_allclose(sim.odom.pose, relative(sim.spawn, sim.robot.pose), atol=1e-12)


def test_sim_config_errors_name_the_parameter() -> None:
    with pytest.raises(ConfigError, match="speed"):
        SimConfig.from_dict({"speed": 0.0})
    with pytest.raises(ConfigError, match="no_return"):
        SimConfig.from_dict({"no_return": "nan"})
    with pytest.raises(ConfigError, match="unknown parameter 'sped'"):
        SimConfig.from_dict({"sped": 2.0})
    with pytest.raises(ConfigError, match="odom_noise"):
        SimConfig.from_dict({"odom_noise": "yes"})
    with pytest.raises(ConfigError, match="range_min"):
        SimConfig.from_dict({"range_min": 4.0})
    assert SimConfig.from_dict({"speed": 4, "seed": 3}).speed == 4.0


def test_spawn_override_route_and_lidar_mount() -> None:
    world = world_from_dict({"segments": [[[3.0, -5.0], [3.0, 5.0]]]})
    cfg = SimConfig(spawn=[1.0, 0.0, 90.0], laser_x=0.1, laser_y=0.05, range_noise=0.0, odom_noise=False)
    sim = Simulation(world, cfg, np.random.default_rng(0), route=np.array([[1.0, 0.5]]))
    np.testing.assert_allclose(sim.spawn, [1.0, 0.0, math.pi / 2])
    assert sim.lidar.mount == (0.1, 0.05, 0.0)
    ticks = [sim.step() for _ in range(12)]
    # 60 Hz ticks: odometry (30 Hz) every 2nd tick from the 2nd, the first scan (5 Hz) at tick 12
    assert [t.odom_due for t in ticks] == [False, True] * 6
    assert [t.scan is not None for t in ticks] == [False] * 11 + [True]
    assert ticks[-1].t == pytest.approx(0.2)
    # facing +y, the sensor sits at (x - 0.05, y + 0.1) and its beam at -90 deg looks along +x
    x, _, heading = sim.robot.pose
    assert heading == pytest.approx(math.pi / 2, abs=1e-12)
    assert ticks[-1].scan[270] == pytest.approx(3.0 - (x - 0.05), abs=1e-9)
    while not sim.step().route_finished:
        assert sim.time < 10.0
    assert math.hypot(*(sim.robot.pose[:2] - [1.0, 0.5])) < cfg.route_tolerance
    v_stopped = sim.robot.pose.copy()
    sim.step()
    np.testing.assert_array_equal(sim.robot.pose, v_stopped)    # a finished route stands still


def test_due_ticks_at_odd_rates() -> None:
    world = world_from_dict({"circles": [[50, 50, 1]]})
    sim = Simulation(world, SimConfig(physics_rate=100.0, odom_rate=30.0, scan_rate=7.0, range_noise=0.0),
                     np.random.default_rng(0))
    ticks = [sim.step() for _ in range(300)]            # 3 s
    assert sum(t.odom_due for t in ticks) == 90 and sum(t.scan is not None for t in ticks) == 21


def test_sim_config_cross_checks() -> None:
    with pytest.raises(ConfigError, match="range_min=3.0 must be below range_max=2.0"):
        SimConfig(range_min=3.0, range_max=2.0)
    with pytest.raises(ConfigError, match="spawn"):
        SimConfig(spawn=[1.0, 2.0])
    assert SimConfig.from_dict({"world": None, "route": None}).world == ""
