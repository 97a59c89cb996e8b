"""Tiles lent to a second process for one update (filter/loan.py): its writes go only into
the tiles lent, so the maps the filter knows are untouched until it takes them; taken, the
maps are those of one process's update, cell for cell, and the pool's counts add up."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.filter import loan
from fastslam.filter.scan import Beams
from fastslam.filter.tiles import SharedTiles, TileMaps, snapshot
from fastslam.filter.trimmed import _part, write_some
from fastslam.filter.weights import Weighing

ANGLES = np.radians(np.arange(0.0, 360.0, 3.0))


def _beams(seed: int) -> Beams:
    rng = np.random.default_rng(seed)
    ranges = rng.uniform(0.8, 2.6, len(ANGLES))
    hit = rng.random(len(ANGLES)) > 0.15              # some beams without a return
    ranges[~hit] = 3.0
    return Beams(ANGLES, ranges, hit, np.where(hit, ranges, 2.5), 0.1)


def _args(maps: TileMaps, beams: Beams, poses: np.ndarray) -> tuple:
    angles = poses[:, 2, None] + beams.angles[None, :]
    weighing = Weighing(poses, beams, 0.05, 0.15, 0.015, 4.5)
    steps = maps.steps(-4, 9, -100, 100)
    return (poses[:, :2].copy(), angles, beams, steps, {"max_range": 2.5, "groups": 4, "free_step": 1}, weighing)


def _poses(n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).normal(0.0, [0.05, 0.05, 0.02], (n, 3))


@pytest.fixture
def maps() -> TileMaps:
    """4 particles' maps after two scans, particles 1 and 2 sharing every tile (resampled)."""
    m = TileMaps(4, (80, 80), 0.05, (-2.0, -2.0), tile=(8, 8), shared=True)
    for k in range(2):
        write_some(m, _args(m, _beams(k), _poses(4, k)))
    m.reorder(np.array([0, 2, 2, 3]))
    return m


def _consistent(m: TileMaps) -> None:
    """Each tile's reference count is the number of table slots holding it; the free ones are held by none."""
    pool = m.pool
    held = np.bincount(m.table.reshape(-1), minlength=pool.top)[1:pool.top]
    np.testing.assert_array_equal(pool.refs[1:pool.top], held)
    free = pool.free_ids()
    assert len(np.unique(free)) == len(free) and not held[free - 1].any()
    assert pool.used == np.count_nonzero(held)


def _lent_write(m: TileMaps, first: int, args: tuple, per_particle: int) -> tuple:
    """The worker's side, in this process: (the loan, its answer for repay, its log-weights)."""
    bound = loan.reach_tiles(m, args[0], 2.5 + 0.1)
    lent = loan.lend(m, first, m.particles, per_particle or bound, bound)
    reader = SharedTiles(writable=True)
    theirs = loan.lent_maps(reader.maps(snapshot(m.view(first, m.particles))), reader.tiles, lent.ids)
    log_w = write_some(theirs, _part(args, first, m.particles))
    return lent, loan.changes(theirs), log_w


def test_the_worker_writes_only_lent_tiles_and_repaid_the_maps_are_one_process_s(maps):
    reference = maps.copy()
    args = _args(maps, _beams(7), _poses(4, 7))
    expected_log_w = write_some(reference, args)
    originals = [maps.particle_map(p) for p in range(4)]

    lent, answer, there = _lent_write(maps, 2, args, 0)
    assert answer[2] > 0
    for p in range(4):     # nothing the filter knows has changed yet
        np.testing.assert_array_equal(maps.particle_map(p), originals[p])
    here = write_some(maps.view(0, 2), _part(args, 0, 2))
    loan.repay(maps, lent, *answer)

    np.testing.assert_array_equal(np.concatenate([here, there]), expected_log_w)
    for p in range(4):
        np.testing.assert_array_equal(maps.particle_map(p), reference.particle_map(p))
        assert (maps.particle_map(p) != originals[p]).sum() > 100
    _consistent(maps)
    assert maps.pool.used == reference.pool.used   # particle 1 copied the tile it shared with 2, 2 wrote a copy


def test_a_refund_leaves_the_maps_and_the_pool_as_they_were(maps):
    originals = [maps.particle_map(p) for p in range(4)]
    table, top, used = maps.table.copy(), maps.pool.top, maps.pool.used
    lent, answer, _ = _lent_write(maps, 1, _args(maps, _beams(7), _poses(4, 7)), 0)
    assert answer[2] > 0 and lent.ids.max() >= top    # fresh tiles were lent and written
    loan.refund(maps, lent)
    np.testing.assert_array_equal(maps.table, table)
    assert maps.pool.top == top and maps.pool.used == used
    for p in range(4):
        np.testing.assert_array_equal(maps.particle_map(p), originals[p])
    _consistent(maps)


def test_a_worker_short_of_tiles_says_so(maps):
    with pytest.raises(loan.OutOfTiles, match="lent"):
        _lent_write(maps, 2, _args(maps, _beams(7), _poses(4, 7)), 1)


def test_the_bound_counts_the_tiles_within_reach_inside_the_table():
    m = TileMaps(2, (80, 80), 0.05, (-2.0, -2.0), tile=(8, 8))     # 10 x 10 tiles of 0.4 m
    assert loan.reach_tiles(m, np.array([[0.0, 0.0]]), 0.5) == 16     # cells 30..50 of each axis: tiles 3..6
    assert loan.reach_tiles(m, np.array([[0.0, 0.0], [0.4, 0.0]]), 0.5) == 20   # columns to cell 58: tile 7
    assert loan.reach_tiles(m, np.array([[0.0, 0.0]]), 10.0) == 100         # clipped to the table
