"""TileMaps: copy-on-write tiles shared between particles. Isolation of particles that
shared a tile, resampling by references, growth without allocation, reference counts
and the free list, unknown reads of tiles never written, the ray tracer's two ways into
the tiles (a dense patch, a translated lookup) against the dense grids, and memory."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.filter import raycast
from fastslam.filter.grid import GridMaps, LogOddsSteps
from fastslam.filter.rays import trace
from fastslam.filter.tiles import TileLookup, TileMaps, TilePatch, TilePool

TILE = (4, 8)   # small tiles: the lattice by hand


def _tiles(n: int = 2, shape: tuple[int, int] = (8, 16), origin: tuple[float, float] = (0.0, 0.0)) -> TileMaps:
    return TileMaps(n, shape, 1.0, origin, tile=TILE)


def test_a_fresh_map_holds_no_tile_and_reads_unknown():
    maps = _tiles(3, (10, 20))
    assert maps.table.shape == (3, 3, 3)                      # ceil(10 / 4) x ceil(20 / 8) tiles
    assert not maps.table.any() and maps.pool.used == 0 and maps.pool.top == 1
    assert maps.values([0, 1, 2], [0, 5, 9], [0, 10, 19]).tolist() == [0, 0, 0]
    assert not maps.particle_map(2).any() and maps.particle_map(2).shape == (10, 20)
    assert maps.known_cells().tolist() == [0, 0, 0]
    assert maps.pool.top == 1                                  # reading allocated nothing


def test_a_write_allocates_the_tile_of_the_cell_only():
    maps = _tiles()
    maps.put(1, 5, 9, 7)                                       # row 5 -> tile row 1; column 9 -> tile column 1
    assert maps.table[1].tolist() == [[0, 0], [0, 1]] and not maps.table[0].any()
    assert maps.pool.used == 1 and maps.pool.refs[1] == 1
    assert maps.values([0, 1, 1], [5, 5, 4], [9, 9, 8]).tolist() == [0, 7, 0]
    expected = np.zeros((8, 16), dtype=np.int8)
    expected[5, 9] = 7
    np.testing.assert_array_equal(maps.particle_map(1), expected)


def test_resampling_shares_references_and_copies_no_cell():
    maps = _tiles(3)
    maps.put(0, [0, 5], [0, 9], [3, 4])                        # particle 0: tiles (0, 0) and (1, 1)
    maps.put(2, 0, 0, 5)                                       # particle 2: tile (0, 0)
    assert maps.pool.used == 3
    maps.reorder(np.array([0, 0, 0]))                          # slots 1 and 2 take particle 0's map
    np.testing.assert_array_equal(maps.table[1], maps.table[0])
    np.testing.assert_array_equal(maps.table[2], maps.table[0])
    assert maps.pool.used == 2 and maps.pool.top == 4          # particle 2's old tile freed, none allocated
    assert maps.pool.refs[maps.table[0, 0, 0]] == 3 and maps.pool.refs[maps.table[0, 1, 1]] == 3
    assert maps.pool.free_ids().tolist() == [3]
    assert maps.values([0, 1, 2], [5, 5, 5], [9, 9, 9]).tolist() == [4, 4, 4]


def test_a_write_into_a_shared_tile_copies_it_for_the_writer_alone():
    maps = _tiles(2)
    maps.put(0, [1, 2], [1, 2], [6, -6])
    maps.reorder(np.array([0, 0]))
    shared = int(maps.table[0, 0, 0])
    assert maps.pool.refs[shared] == 2
    maps.put(1, 1, 1, 9)                                       # particle 1 writes into the shared tile
    assert maps.table[0, 0, 0] == shared and maps.table[1, 0, 0] != shared
    assert maps.pool.refs[shared] == 1 and maps.pool.refs[maps.table[1, 0, 0]] == 1
    assert maps.values([0, 1, 0, 1], [1, 1, 2, 2], [1, 1, 2, 2]).tolist() == [6, 9, -6, -6]   # the copy kept -6
    maps.put(0, 2, 2, 1)                                       # particle 0 now holds its tile alone: in place
    assert maps.table[0, 0, 0] == shared and maps.pool.used == 2
    assert maps.values([0, 1], [2, 2], [2, 2]).tolist() == [1, -6]


def test_a_tile_every_holder_writes_stays_with_one_of_them():
    maps = _tiles(3)
    maps.put(0, 0, 0, 2)
    maps.reorder(np.array([0, 0, 0]))
    before = maps.pool.top
    maps.put([0, 1, 2], [0, 0, 0], [1, 2, 3], [1, 2, 3])        # all three write the shared tile at once
    ids = maps.table[:, 0, 0]
    assert len(set(ids.tolist())) == 3 and maps.pool.top == before + 2   # two copies, the first keeps it
    assert maps.pool.refs[ids].tolist() == [1, 1, 1]
    assert maps.values([0, 1, 2, 1], [0, 0, 0, 0], [1, 2, 3, 1]).tolist() == [1, 2, 3, 0]
    assert maps.values([0, 1, 2], [0, 0, 0], [0, 0, 0]).tolist() == [2, 2, 2]


def test_freed_tiles_are_reused_before_new_ones():
    maps = _tiles(2)
    maps.put(1, [0, 4], [0, 8], [1, 1])                        # particle 1: tiles 1, 2
    maps.reorder(np.array([0, 0]))                             # particle 1 drops its map: both freed
    assert maps.pool.used == 0 and sorted(maps.pool.free_ids().tolist()) == [1, 2]
    maps.put(0, 0, 8, 5)
    assert int(maps.table[0, 0, 1]) in (1, 2) and maps.pool.top == 3     # a freed id, not a new one
    assert maps.pool.refs[maps.table[0, 0, 1]] == 1


def test_growth_reindexes_the_tables_only_and_keeps_world_coordinates():
    maps = _tiles(2, (8, 16), origin=(0.0, 0.0))
    maps.put(1, 5, 9, 7)
    top, tiles_bytes = maps.pool.top, maps.pool.nbytes
    assert maps.growth_bytes(-3.0, -2.0, 10.0, 7.0, fraction=0.0) == 2 * (3 * 3) * 4   # the grown tables
    assert maps.grow_to(-3.0, -2.0, 10.0, 7.0, fraction=0.0)   # 3 cells left, 2 down; as dense grids grow
    assert maps.shape == (10, 19) and list(maps.origin) == [-3.0, -2.0]
    # the lattice stays put in the world: 2 rows below need a tile row (offset 4 - 2 = 2),
    # 3 columns left a tile column (offset 8 - 3 = 5)
    assert maps.offset == (2, 5) and maps.table.shape == (2, 3, 3)
    assert maps.pool.top == top and maps.pool.nbytes == tiles_bytes       # no tile allocated
    assert maps.values(1, 5 + 2, 9 + 3) == 7
    expected = np.zeros((10, 19), dtype=np.int8)
    expected[7, 12] = 7
    np.testing.assert_array_equal(maps.particle_map(1), expected)


def test_growth_matches_the_dense_grids_cell_for_cell():
    rng = np.random.default_rng(3)
    dense, tiled = GridMaps(3, (13, 21), 0.5, (-2.0, 1.0)), TileMaps(3, (13, 21), 0.5, (-2.0, 1.0), tile=TILE)
    for box in [(-4.3, 0.2, 9.0, 8.0), (-9.0, -6.0, 9.0, 8.0), (-9.0, -6.0, 20.0, 30.0)]:
        n, iy, ix = rng.integers(0, 3, 40), rng.integers(0, dense.shape[0], 40), rng.integers(0, dense.shape[1], 40)
        v = rng.integers(-100, 100, 40)
        dense.put(n, iy, ix, v)
        tiled.put(n, iy, ix, v)
        assert dense.grow_to(*box, fraction=0.3) and tiled.grow_to(*box, fraction=0.3)
        assert tiled.shape == dense.shape and np.array_equal(tiled.origin, dense.origin)
        for i in range(3):
            np.testing.assert_array_equal(tiled.particle_map(i), dense.particle_map(i))


def test_the_pool_grows_in_place_and_keeps_every_tile():
    maps = _tiles(1, (64, 64))
    maps.pool = TilePool(TILE, capacity=16)                    # room for 15 tiles: it must grow
    capacity, memory = maps.pool.capacity, maps.pool._map
    iy, ix = np.meshgrid(np.arange(0, 64, 4), np.arange(0, 64, 8), indexing="ij")   # one cell in each of 128 tiles
    maps.put(0, iy.ravel(), ix.ravel(), (np.arange(iy.size) % 100 + 1))
    assert maps.pool.capacity > capacity >= 2 and maps.pool.used == 128
    assert maps.pool._map is memory                            # resized in place: no view of it was alive
    assert maps.values(0, iy.ravel(), ix.ravel()).tolist() == (np.arange(iy.size) % 100 + 1).tolist()


def test_reads_through_the_api_equal_the_dense_grids():
    rng = np.random.default_rng(0)
    dense, tiled = GridMaps(4, (23, 37), 0.1, (0.0, 0.0)), TileMaps(4, (23, 37), 0.1, (0.0, 0.0), tile=TILE)
    n, iy, ix = rng.integers(0, 4, 300), rng.integers(0, 23, 300), rng.integers(0, 37, 300)
    v = rng.integers(-127, 128, 300)
    dense.put(n, iy, ix, v)
    tiled.put(n, iy, ix, v)
    tiled.reorder(np.array([0, 0, 2, 2]))
    dense.reorder(np.array([0, 0, 2, 2]))
    q = (rng.integers(0, 4, (5, 6)), rng.integers(2, 21, (5, 6)), rng.integers(2, 35, (5, 6)))
    np.testing.assert_array_equal(tiled.values(*q), dense.values(*q))
    d = np.arange(-2, 3)
    dy, dx = (a.ravel() for a in np.meshgrid(d, d, indexing="ij"))
    np.testing.assert_array_equal(tiled.values_around(*q, dy, dx), dense.values_around(*q, dy, dx))
    np.testing.assert_array_equal(tiled.crop(3, 19, 5, 30, 1, 4), dense.crop(3, 19, 5, 30, 1, 4))
    np.testing.assert_array_equal(tiled.known_cells(), dense.known_cells())
    for i in range(4):
        np.testing.assert_array_equal(tiled.occupancy(i), dense.occupancy(i))
    np.testing.assert_array_equal(tiled.view(2).particle_map(0), dense.particle_map(2))
    copied = tiled.copy()
    copied.put(0, 0, 0, 99)
    assert copied.values(0, 0, 0) == 99 and tiled.values(0, 0, 0) == dense.values(0, 0, 0)


@pytest.mark.parametrize("few", [0, 1 << 30])
def test_values_around_reads_the_dense_grids_cells_by_tile_or_cell_by_cell(few, monkeypatch):
    # few = 0: each point's kernel from its own cell's tile (and edge points cell by cell);
    # else every cell's tile looked up: the same cells, kernels inside a tile or across its edges
    monkeypatch.setattr("fastslam.filter.tiles.FEW_CELLS", few)
    rng = np.random.default_rng(1)
    dense, tiled = GridMaps(3, (40, 50), 0.1, (0.0, 0.0)), TileMaps(3, (40, 50), 0.1, (0.0, 0.0), tile=(8, 16))
    n, iy, ix = rng.integers(0, 3, 2000), rng.integers(0, 40, 2000), rng.integers(0, 50, 2000)
    v = rng.integers(-127, 128, 2000)
    dense.put(n, iy, ix, v)
    tiled.put(n, iy, ix, v)
    tiled.grow_to(-0.3, -0.5, 5.2, 4.1, fraction=0.0)     # the lattice offset no longer zero
    dense.grow_to(-0.3, -0.5, 5.2, 4.1, fraction=0.0)
    h, w = tiled.shape
    d = np.arange(-2, 3)
    dy, dx = (a.ravel() for a in np.meshgrid(d, d, indexing="ij"))
    for q in ((np.arange(3)[:, None], rng.integers(2, h - 2, (3, 40)), rng.integers(2, w - 2, (3, 40))),
              (np.arange(3)[:, None, None], rng.integers(2, h - 2, (4, 7)), rng.integers(2, w - 2, (3, 4, 7))),
              (rng.integers(0, 3, 9), rng.integers(2, h - 2, 9), rng.integers(2, w - 2, 9))):
        np.testing.assert_array_equal(tiled.values_around(*q, dy, dx), dense.values_around(*q, dy, dx))


@pytest.mark.parametrize("way", [TilePatch, TileLookup])
def test_the_ray_tracer_writes_through_either_way_as_into_dense_grids(way, monkeypatch):
    monkeypatch.setattr("fastslam.filter.tiles.PATCH_FACTOR", 1e9 if way is TilePatch else 0.0)
    rng = np.random.default_rng(7)
    dense = GridMaps(4, (60, 70), 0.1, (-3.0, -3.0))
    tiled = TileMaps(4, (60, 70), 0.1, (-3.0, -3.0), tile=TILE)
    steps = LogOddsSteps(-4, 9, -100, 100)
    angles = np.radians(np.arange(0.0, 360.0, 7.0))
    for t in range(6):
        origins = rng.uniform(-1.0, 1.0, (4, 2))
        a = np.tile(angles, (4, 1)) + rng.normal(0, 0.1, (4, len(angles)))
        ranges = rng.uniform(0.3, 2.5, len(angles))
        for maps in (dense, tiled):
            rays = trace(maps, origins, a, 2.0)
            if maps is tiled:
                assert isinstance(rays.space, way)
            expected = raycast.expected_ranges(maps, rays, 0.1)
            ends = rays.step_of_range(ranges)
            raycast.update_logodds(maps, rays, ends, ends, first_step=np.zeros_like(ends), steps=steps)
            rays.space.close()
            if maps is dense:
                want = expected
        np.testing.assert_array_equal(expected, want)
        parent = np.array([0, 0, 1, 3]) if t % 2 else np.arange(4)
        dense.reorder(parent)
        tiled.reorder(parent)
    for i in range(4):
        np.testing.assert_array_equal(tiled.particle_map(i), dense.particle_map(i))
    assert tiled.known_cells().min() > 0


def test_a_patch_that_changes_nothing_allocates_nothing():
    maps = _tiles(2, (16, 32))
    space = maps.cells(0, 2, (0, 0), (32, 16))
    assert isinstance(space, TilePatch)
    space.close()
    assert maps.pool.top == 1 and not maps.table.any()


def test_memory_counts_the_tiles_used_and_the_tables():
    maps = TileMaps(30, (2000, 2000), 0.05, (0.0, 0.0), tile=(32, 64))
    tables = 30 * 63 * 32 * 4                                   # ceil(2000 / 32) x ceil(2000 / 64) int32 ids
    assert TileMaps.bytes_for(30, (2000, 2000), (32, 64)) == tables
    assert maps.nbytes == tables + maps.pool.nbytes and maps.pool.nbytes < 64 * 1024
    before = maps.nbytes
    maps.put(np.arange(30), 100, 100, 1)                        # one tile per particle
    assert maps.nbytes - before == 30 * 32 * 64                 # 30 tiles of 2 KiB (their counts were reserved)
    assert GridMaps.bytes_for(30, (2000, 2000)) == 30 * 2000 * 2000


def test_shared_tiles_read_a_snapshot_through_the_memory_file_as_the_pool_grows():
    from fastslam.filter.tiles import SharedTiles, snapshot
    rng = np.random.default_rng(5)
    maps = TileMaps(2, (200, 260), 0.05, (-1.0, 2.0), shared=True, tile=(16, 16))
    maps.pool = TilePool((16, 16), capacity=16, shared=True)   # room for 15 tiles: it must grow
    reader = SharedTiles()
    capacities = []
    for _ in range(3):
        iy, ix = rng.integers(0, 200, 400), rng.integers(0, 260, 400)
        maps.put(1, iy, ix, rng.integers(-90, 90, 400).astype(np.int8))
        seen = reader.maps(snapshot(maps.view(1)))          # as a second process reads it
        np.testing.assert_array_equal(seen.crop(0, 200, 0, 260), maps.crop(0, 200, 0, 260, 1, 2))
        assert seen.values(0, iy[:5], ix[:5]).tolist() == maps.values(1, iy[:5], ix[:5]).tolist()
        capacities.append((maps.pool.capacity, len(reader.tiles)))
    # 221 tiles in all: the pool grew from 16 and the reader mapped the grown file
    assert capacities[0][0] > 16 and all(pool <= read for pool, read in capacities), capacities
    before = seen.crop(0, 200, 0, 260).copy()
    assert maps.grow_to(-3.0, 0.0, 12.0, 14.0, fraction=0.0)   # the filter's tables change: a snapshot keeps its own
    np.testing.assert_array_equal(seen.crop(0, 200, 0, 260), before)


def test_only_maps_in_shared_memory_can_be_snapshot():
    from fastslam.filter.tiles import snapshot
    with pytest.raises(ValueError, match="not shared"):
        snapshot(TileMaps(1, (64, 64), 0.05, (0.0, 0.0)).view(0))


def test_cleared_maps_read_unknown_and_free_every_tile_nothing_else_holds():
    maps = _tiles(2)
    maps.put(0, [0, 5], [0, 9], [3, 4])                        # particle 0: tiles (0, 0) and (1, 1)
    maps.put(1, 0, 0, 5)                                       # particle 1: tile (0, 0), its own
    held = int(maps.table[0, 1, 1])
    maps.pool.hold(np.array([held]))                           # as the tracked map holds its tiles
    maps.clear()
    assert not maps.table.any() and not maps.particle_map(0).any() and not maps.particle_map(1).any()
    assert maps.pool.used == 1 and maps.pool.refs[held] == 1   # the held tile stays, and reads as it was
    assert sorted(maps.pool.free_ids().tolist()) == sorted({1, 2, 3} - {held})
    dense = GridMaps(2, (8, 16), 1.0, (0.0, 0.0))
    dense.put([0, 1], [2, 3], [4, 5], [7, -7])
    dense.clear()
    assert not dense.logodds.any()
