"""A robot pushed against a wall: the simulated laser reads too close, never "no return",
so the filter clears no free space through the wall; the contact is reported once."""
import numpy as np

from fastslam.config import SlamConfig
from fastslam.filter.scan import Scan
from fastslam.filter.slam import FastSlam
from fastslam.sim.lidar import driver_ranges
from fastslam.sim.sim import SimConfig, Simulation
from fastslam.sim.world import world_from_dict

BOX = world_from_dict({"spawn": [0.0, 0.0, 0.0],
                       "polygons": [{"points": [[-2, -2], [2, -2], [2, 2], [-2, 2]], "solid": False}]})


def reverse_into_the_west_wall(no_return: str = "inf"):
    """Backs the burger into x = -2 for 15 s of sim time, mapping every scan with one
    noise-free particle and perfect odometry. Returns (filter, bumps, scans, cfg)."""
    cfg = SimConfig.from_dict({"odom_noise": False, "range_noise": 0.0, "no_return": no_return})
    sim = Simulation(BOX, cfg, np.random.default_rng(0))
    slam = FastSlam(SlamConfig(particles=1, toggle_noise=0, seed=0))
    angles = sim.lidar.angles
    bumps, scans = 0, []
    while sim.time < 15.0:
        sim.set_cmd(-0.22, 0.0)
        tick = sim.step()
        bumps += tick.bumped
        if tick.scan is not None:
            ranges = driver_ranges(tick.scan, cfg.range_min, cfg.no_return)
            scans.append(ranges)
            slam.step(sim.odom.pose.copy(),
                      Scan.from_laser(ranges, float(angles[0]), float(angles[1] - angles[0]), cfg.range_min,
                                      cfg.range_max, mount=sim.lidar.mount, stamp=tick.t))
    return slam, bumps, scans, cfg, sim


def free_cells_beyond_the_wall(slam: FastSlam) -> int:
    occ = slam.best_occupancy()
    iy, ix = np.nonzero((occ >= 0) & (occ < 50))     # known, and more likely free than not
    x = slam.grid.cell_to_world(np.c_[ix, iy])[:, 0]
    # the map frame is the odom frame, which starts at the spawn: the world's origin here
    return int(np.sum(x < -2.0 - slam.grid.resolution))


def test_a_robot_against_a_wall_clears_nothing_behind_it():
    slam, bumps, scans, cfg, sim = reverse_into_the_west_wall()
    # it did reach the wall: the body touches it and the laser (3.2 cm behind the centre)
    # is closer to it than range_min
    assert sim.robot.pose[0] < -2.0 + sim.robot.radius + 0.01   # stopped within a step of the wall
    last = scans[-1]
    back = np.abs(np.degrees(sim.lidar.angles) - 180.0) < 20.0
    assert np.all(last[back] < cfg.range_min) and np.all(np.isfinite(last[back]))
    assert free_cells_beyond_the_wall(slam) == 0
    assert slam.updates == len(scans)
    assert bumps == 1                      # one contact, reported once


def test_the_lds01_driver_mode_reads_zero_and_clears_nothing_either():
    slam, _, scans, cfg, _ = reverse_into_the_west_wall("zero")
    back = np.abs(np.degrees(np.arange(360.0)) - 180.0) < 20.0
    assert np.all(scans[-1][back] == 0.0)
    assert free_cells_beyond_the_wall(slam) == 0


def test_contact_is_reported_again_only_after_leaving_the_wall():
    cfg = SimConfig.from_dict({"odom_noise": False, "range_noise": 0.0})
    sim = Simulation(BOX, cfg, np.random.default_rng(0))
    bumps = []
    for v, seconds in ((-0.22, 12.0), (0.0, 2.0), (-0.22, 2.0), (0.1, 2.0), (-0.22, 4.0)):
        end = sim.time + seconds
        while sim.time < end:
            sim.set_cmd(v, 0.0)
            if sim.step().bumped:
                bumps.append(round(sim.time, 1))
    # the first push, nothing while standing or pushing again, a second contact after moving away
    assert len(bumps) == 2 and bumps[0] < 12.0 and bumps[1] > 18.0
