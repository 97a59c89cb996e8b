"""The filter's bounds: growth refused past max_map_extent or the memory limit, mapping on
inside; a configuration whose first maps cannot fit is refused at start-up."""
import numpy as np
import pytest

from fastslam.config import SlamConfig
from fastslam.filter import budget
from fastslam.filter.budget import Limits, limit_bytes, reserve_bytes, startup_problem
from fastslam.filter.grid import GridMaps
from fastslam.filter.scan import Scan
from fastslam.filter.slam import FastSlam

ANGLES = np.radians(np.arange(0.0, 360.0, 2.0))
MB = 2**20


def _scan(t):
    return Scan(ranges=np.full(len(ANGLES), 1.0), angles=ANGLES, range_min=0.1, range_max=3.5, stamp=t)


def _drive(slam, xs):
    infos = []
    for i, x in enumerate(xs):
        infos.append(slam.step(np.array([x, 0.0, 0.0]), _scan(float(i))))
    return infos


def test_growth_past_max_map_extent_is_refused_once_and_mapping_goes_on_inside():
    # 10 m maps at 0.05 m (200 cells), at most 20 m: the robot drives 30 m along x
    slam = FastSlam(SlamConfig(particles=2, seed=0, toggle_noise=0), limits=Limits(max_map_extent=20.0))
    infos = _drive(slam, np.arange(0.0, 30.0, 0.5))
    assert all(i.processed for i in infos)
    refused = [i.refused for i in infos if i.refused]
    assert len(refused) == 1 and refused[0].startswith("map growth refused: the map would grow to ")
    assert "beyond max_map_extent 20 m; mapping goes on inside the map" in refused[0]
    h, w = slam.grid.shape
    assert max(h, w) * 0.05 <= 20.0 and w * 0.05 > 15.0          # grew as far as allowed
    assert slam.refusals == sum(i.clipped for i in infos) > 0
    # cells inside the map seen at the end: the robot at x = 29.5 m sees nothing inside, but
    # at 12 m (inside) the ring of hits at 1 m was mapped
    ix = slam.grid.world_to_cell([13.0, 0.0])[0]
    assert slam.grid.values([0, 1], 100, ix).max() > 0


def test_only_what_is_missing_is_grown_when_the_usual_growth_would_pass_the_bound():
    slam = FastSlam(SlamConfig(particles=1, seed=0, toggle_noise=0), limits=Limits(max_map_extent=12.0))
    infos = _drive(slam, [0.0, 2.0])   # the beams reach 5.6 m: 0.6 m past the edge
    assert infos[1].grew and not infos[1].refused
    assert slam.grid.shape == (200, 200 + 13)          # 0.6 m + the edge cell, not half the map


def test_growth_past_the_memory_budget_is_refused(monkeypatch):
    monkeypatch.setattr(FastSlam, "maps_type", GridMaps)   # dense maps: every cell held
    cfg = SlamConfig(particles=4, seed=0, toggle_noise=0)
    maps = GridMaps.bytes_for(4, cfg.grid_shape)       # 160 kB
    slam = FastSlam(cfg, limits=Limits(map_bytes=int(2.5 * maps)))
    infos = _drive(slam, np.arange(0.0, 40.0, 1.0))
    refused = [i.refused for i in infos if i.refused]
    assert len(refused) == 1 and "more than the memory limit leaves them (0.4 MB; memory_limit_mb)" in refused[0]
    # a growth holds the old and the new maps at once: both within the budget
    assert slam.grid.nbytes <= 1.5 * maps and slam.updates == 40


def test_tiled_maps_are_budgeted_by_the_tiles_they_hold():
    cfg = SlamConfig(particles=4, seed=0, toggle_noise=0)
    free = FastSlam(cfg)
    held = []
    for i, x in enumerate(np.arange(0.0, 40.0, 1.0)):
        free.step(np.array([x, 0.0, 0.0]), _scan(float(i)))
        held.append(free.grid.nbytes)
    assert held[-1] < GridMaps.bytes_for(4, free.grid.shape) / 2     # shared tiles: below dense
    limit = held[20]                                                  # what the maps held half way
    slam = FastSlam(cfg, limits=Limits(map_bytes=limit))
    refused = [i.refused for i in _drive(slam, np.arange(0.0, 40.0, 1.0)) if i.refused]
    assert len(refused) == 1 and "memory limit" in refused[0]
    assert slam.grid.shape[1] < free.grid.shape[1] and slam.updates == 40


def test_a_failed_allocation_is_a_refusal_not_a_crash(monkeypatch):
    slam = FastSlam(SlamConfig(particles=2, seed=0, toggle_noise=0))

    def no_memory(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(slam.grid, "grow_to", no_memory)
    infos = _drive(slam, [0.0, 3.0, 6.0])
    assert [bool(i.refused) for i in infos] == [False, True, False] and all(i.processed for i in infos)
    assert "the allocation of" in infos[1].refused and slam.grid.shape == (200, 200)


def test_a_reset_reports_a_refusal_again():
    slam = FastSlam(SlamConfig(particles=1, seed=0, toggle_noise=0), limits=Limits(max_map_extent=10.0))
    assert _drive(slam, [0.0, 3.0])[1].refused
    slam.reset()
    assert _drive(slam, [0.0, 3.0])[1].refused and slam.refusals == 2


def test_a_configuration_that_cannot_fit_fails_at_start_up_naming_the_parameters():
    cfg = SlamConfig(particles=200, map_width=400.0, map_height=400.0)   # 200 x 8000 x 8000 cells
    problem = startup_problem(cfg, Limits.for_memory(4096, 200))
    assert problem == ("memory_limit_mb: particles=200 maps of 400 x 400 m at map_resolution=0.05 m (8000 x 8000 "
                       "cells) need 12208 MB, more than the limit leaves for maps (3893 MB): use fewer particles, "
                       "a smaller map_width/map_height, a coarser map_resolution or a larger memory_limit_mb")
    assert startup_problem(cfg.replace(particles=20), Limits.for_memory(4096, 20)) is None
    assert startup_problem(cfg.replace(particles=20), Limits(max_map_extent=100.0)) == (
        "max_map_extent=100 must be at least map_width/map_height (400 m)")


def test_the_limit_is_given_or_a_share_of_the_machine(monkeypatch):
    assert limit_bytes(3000) == 3000 * MB
    monkeypatch.setattr(budget, "system_memory_bytes", lambda: 10_000 * MB)
    assert limit_bytes(0) == 8000 * MB
    assert Limits.for_memory(0, 10, 100).map_bytes == 8000 * MB - reserve_bytes(10, 100)
    assert reserve_bytes(10, 100) == 128 * MB + 10 * 100 * 96
    monkeypatch.setattr(budget, "system_memory_bytes", lambda: None)
    assert Limits.for_memory(0, 10).map_bytes is None


def test_the_system_memory_is_the_least_of_what_bounds_it(monkeypatch):
    import resource

    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    assert budget.system_memory_bytes() > 0
    resource.setrlimit(resource.RLIMIT_AS, (2**40, hard))   # a 1 TiB ulimit: the machine's memory is less
    try:
        assert budget.system_memory_bytes() < 2**40
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
    monkeypatch.setattr(budget.resource, "getrlimit", lambda which: (3 * 2**30, resource.RLIM_INFINITY))
    assert budget.system_memory_bytes() <= 3 * 2**30


@pytest.mark.parametrize("particles", [1, 30])
def test_start_up_limit_is_the_maps_share(particles):
    cfg = SlamConfig(particles=particles)
    need = GridMaps.bytes_for(particles, cfg.grid_shape)
    assert startup_problem(cfg, Limits(map_bytes=need)) is None
    assert startup_problem(cfg, Limits(map_bytes=need - 1)) is not None
