"""GridMaps: int8 log-odds quantisation, cell <-> world, growth keeping content, reordering
after resampling, occupancy in ROS's convention."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastslam.filter.grid import GridMaps, LogOddsSteps, logodds_to_occupancy

RES = 0.1


def test_quantise_rounds_to_the_nearest_step_and_never_to_zero():
    grid = GridMaps(1, (4, 4), 0.1, (0.0, 0.0), l_limit=5.0)
    assert grid.scale == pytest.approx(5.0 / 127)
    assert grid.quantise(0.85) == 22                  # 0.85 / 0.03937 = 21.59
    assert grid.quantise(-0.4) == -10                 # -10.16
    assert grid.quantise(0.01) == 1                   # 0.25 of a step: rounds to 0, kept at one step
    assert grid.quantise(-0.001) == -1
    assert grid.quantise(100.0) == 127 and grid.quantise(-100.0) == -127   # clamped to int8
    assert grid.steps(-0.4, 0.85, -5.0, 5.0) == LogOddsSteps(free=-10, occ=22, lo=-127, hi=127)


def test_the_limit_sets_the_scale():
    grid = GridMaps(1, (4, 4), 0.1, (0.0, 0.0), l_limit=2.54)
    assert grid.quantise(0.02) == 1 and grid.quantise(0.05) == 2 and grid.quantise(2.54) == 127


def test_world_to_cell_and_back():
    grid = GridMaps(1, (6, 8), 0.25, (-1.0, -0.5))
    np.testing.assert_array_equal(grid.world_to_cell(np.array([0.1, 0.3])), [4, 3])       # 4.4, 3.2
    np.testing.assert_array_equal(grid.world_to_cell(np.array([[-1.0, -0.5], [-1.01, -0.5]])),
                                  [[0, 0], [-1, 0]])       # the corner is in cell 0; left of it is outside
    np.testing.assert_allclose(grid.cell_to_world(np.array([4, 3])), [0.125, 0.375])      # the centre
    cells = np.stack(np.meshgrid(np.arange(8), np.arange(6)), -1).reshape(-1, 2)
    np.testing.assert_array_equal(grid.world_to_cell(grid.cell_to_world(cells)), cells)
    pts = np.random.default_rng(0).uniform([-1.0, -0.5], [1.0, 1.0], (200, 2))
    np.testing.assert_array_less(np.abs(grid.cell_to_world(grid.world_to_cell(pts)) - pts), 0.125 + 1e-12)


def test_extent_and_covers():
    grid = GridMaps(2, (6, 8), 0.25, (-1.0, -0.5))
    assert grid.shape == (6, 8)
    assert grid.extent == (-1.0, -0.5, 1.0, 1.0)
    assert grid.covers(-1.0, -0.5, 0.99, 0.99)
    assert not grid.covers(-1.0, -0.5, 1.0, 0.5)       # the far edges belong to the next cell
    assert not grid.covers(-1.01, -0.5, 0.5, 0.5)


def test_grow_by_what_is_missing_when_the_fraction_is_zero():
    grid = GridMaps(1, (10, 10), 1.0, (0.0, 0.0))
    assert grid.grow_to(-2.5, 0.0, 5.0, 5.0, fraction=0.0)
    assert grid.shape == (10, 13) and list(grid.origin) == [-3.0, 0.0]     # ceil(2.5) cells on the left
    assert grid.extent == (-3.0, 0.0, 10.0, 10.0)
    assert grid.grow_to(-3.0, 0.0, 10.0, 5.0, fraction=0.0)
    assert grid.shape == (10, 14)                      # x = 10 lies in the cell beyond the edge: one column
    assert not grid.grow_to(-3.0, 0.0, 10.9, 9.9, fraction=0.0)


def test_grow_keeps_content_at_its_world_place():
    grid = GridMaps(2, (20, 20), RES, (-1.0, -1.0))
    grid.logodds[1, 3, 4] = 7
    before = grid.cell_to_world(np.array([4, 3]))
    assert grid.grow_to(-3.0, -1.0, 0.5, 2.5)
    h, w = grid.shape
    assert h >= 35 and w >= 40
    iy, ix = np.argwhere(grid.logodds[1] == 7)[0]
    np.testing.assert_allclose(grid.cell_to_world(np.array([ix, iy])), before)
    assert grid.covers(-3.0, -1.0, 0.5, 2.5)
    assert not grid.grow_to(-3.0, -1.0, 0.5, 2.5)


def test_map_grows_and_keeps_content_at_its_world_place():
    grid = GridMaps(2, (20, 30), 0.1, (-1.5, -1.0))
    marks = np.array([[-1.45, -0.95], [1.45, 0.95], [0.05, 0.05]])
    cells = grid.world_to_cell(marks)
    grid.logodds[1, cells[:, 1], cells[:, 0]] = [11, 22, 33]
    assert grid.grow_to(-4.0, -1.0, 1.0, 6.0)
    x0, y0, x1, y1 = grid.extent
    assert x0 <= -4.0 and y0 <= -1.0 and x1 > 1.0 and y1 > 6.0
    cells = grid.world_to_cell(marks)
    np.testing.assert_array_equal(grid.logodds[1, cells[:, 1], cells[:, 0]], [11, 22, 33])
    assert np.count_nonzero(grid.logodds) == 3
    h, w = grid.shape
    assert (h - 20) >= 10 and (w - 30) >= 15                 # at least half the size: amortised
    assert not grid.grow_to(-3.9, -0.9, 0.9, 5.9)           # already covered: no copy


def test_grow_fraction_sets_the_least_growth_of_a_side():
    for fraction, least in ((0.5, 50), (0.1, 10)):
        g = GridMaps(1, (100, 100), 0.1, (0.0, 0.0))
        g.grow_to(-0.05, 0.0, 9.0, 9.0, fraction=fraction)    # one cell short on the left
        assert g.shape == (100, 100 + least)
        np.testing.assert_allclose(g.origin, [-least * 0.1, 0.0])


def _numbered(n: int) -> GridMaps:
    """n maps of 3 x 4 cells, map i filled with i + 1."""
    grid = GridMaps(n, (3, 4), 0.1, (0.0, 0.0))
    grid.logodds[:] = (np.arange(n) + 1)[:, None, None]
    return grid


def test_reorder_gives_each_slot_its_parents_map():
    grid = _numbered(4)
    grid.reorder(np.array([0, 0, 2, 2]))               # slots 1 and 3 take copies of 0 and 2
    np.testing.assert_array_equal(grid.logodds[:, 0, 0], [1, 1, 3, 3])
    assert np.all(grid.logodds == grid.logodds[:, :1, :1])


def test_reorder_copies_only_the_moved_slots(monkeypatch):
    grid = _numbered(5)
    copied = []
    real_copyto = np.copyto

    def counting(dst, src, *args, **kwargs):
        copied.append(int(src[0, 0]))
        real_copyto(dst, src, *args, **kwargs)

    monkeypatch.setattr(np, "copyto", counting)
    grid.reorder(np.array([0, 0, 2, 3, 3]))            # slot 1 <- 0, slot 4 <- 3; 0, 2, 3 stay
    assert copied == [1, 4]                             # two maps copied, from slots 0 and 3
    np.testing.assert_array_equal(grid.logodds[:, 2, 3], [1, 1, 3, 4, 4])


def test_reorder_of_the_identity_writes_nothing():
    grid = _numbered(3)
    grid.logodds.flags.writeable = False                # any write would raise
    grid.reorder(np.arange(3))
    np.testing.assert_array_equal(grid.logodds[:, 1, 1], [1, 2, 3])


def test_reorder_reads_every_source_before_writing():
    grid = _numbered(3)
    grid.reorder(np.array([1, 0, 2]))                   # a swap: a map-by-map copy would lose map 1
    np.testing.assert_array_equal(grid.logodds[:, 0, 0], [2, 1, 3])


def test_occupancy_conversion():
    occ = logodds_to_occupancy(np.array([0, 127, -127, 20], dtype=np.int8), scale=5 / 127)
    assert list(occ) == [-1, 99, 1, 69]


def test_probability_occupancy_and_known_cells_of_a_particle():
    grid = GridMaps(2, (1, 3), 0.1, (0.0, 0.0), l_limit=5.0)
    grid.logodds[1] = [[0, 127, -127]]
    grid.logodds[0, 0, 0] = 1
    p = grid.probability(1)
    np.testing.assert_allclose(p, [[0.5, 1 / (1 + math.exp(-5)), 1 / (1 + math.exp(5))]])
    np.testing.assert_array_equal(grid.occupancy(1), [[-1, 99, 1]])    # 0.9933 -> 99, 0.0067 -> 1
    assert grid.occupancy(1).dtype == np.int8
    np.testing.assert_array_equal(grid.occupancy(0), [[51, -1, -1]])   # one step: p = 0.5098
    np.testing.assert_array_equal(grid.known_cells(), [1, 2])


def test_a_view_shares_some_particles_cells():
    grid = GridMaps(3, (4, 5), RES, (1.0, -2.0))
    grid.logodds[1, 2, 3] = 7
    one = grid.view(1)
    assert one.logodds.shape == (1, 4, 5) and one.shape == (4, 5) and one.particles == 1
    assert one.logodds[0, 2, 3] == 7 and np.shares_memory(one.logodds, grid.logodds)
    assert one.resolution == RES and tuple(one.origin) == (1.0, -2.0)
    grid.logodds[1, 0, 0] = -3                     # later writes show through
    assert one.logodds[0, 0, 0] == -3
    two = grid.view(1, 3)
    assert two.particles == 2 and two.values([0, 1], [2, 2], [3, 3]).tolist() == [7, 0]


# -- memory: what the maps hold and what a growth would allocate (the node's budget) ---------

def test_bytes_of_the_maps_and_of_a_growth():
    g = GridMaps(3, (20, 10), 0.5, (0.0, 0.0))
    assert g.nbytes == 3 * 20 * 10 == GridMaps.bytes_for(3, (20, 10))
    assert g.growth_bytes(1.0, 1.0, 4.0, 9.0) == 0            # covered: nothing to allocate
    # 1 m past the right edge (x 5 -> 6): 2 cells + 1 (the edge cell), at least half of 10
    assert g.grown_shape(0.0, 0.0, 6.0, 9.0) == (20, 15)
    assert g.grown_shape(0.0, 0.0, 6.0, 9.0, fraction=0.0) == (20, 13)
    assert g.growth_bytes(0.0, 0.0, 6.0, 9.0) == 3 * 20 * 15   # the whole new maps: the old ones go after the copy
    g.grow_to(0.0, 0.0, 6.0, 9.0)
    assert g.shape == (20, 15) and g.nbytes == 3 * 20 * 15


def test_occupancy_of_int8_grids_by_table_equals_the_formula():
    values = np.arange(-128, 128).astype(np.int8).reshape(16, 16)
    for scale in (5 / 127, 0.3):
        table = logodds_to_occupancy(values, scale)
        formula = logodds_to_occupancy(values.astype(np.int16), scale)     # the float path
        np.testing.assert_array_equal(table, formula)
        assert table.dtype == np.int8 and table.shape == (16, 16)
    strided = values[:, ::3]                                                # not contiguous
    np.testing.assert_array_equal(logodds_to_occupancy(strided, 0.3), logodds_to_occupancy(values, 0.3)[:, ::3])
