"""Tiles lent to another process for one update: the second process (filter/pipeline.py)
writes the scan into the maps of some particles while the filter writes the others'.

The tile pool is a memory file both processes map. The filter lends the worker free tile
ids (lend: a few times what an update of a particle writes; all the tiles within the
beams' reach would be 10-20 times that, and the pool would grow by as much), and the
worker writes each tile it changes into one of those, a copy, never into a tile the
filter knows (LentMaps). So its particles' tables change only when the filter takes its
answer (repay): until then they hold the maps as before the scan, and a worker that fails
leaves nothing to undo (refund; the filter writes them itself).

The filter's own writes meanwhile go in place only into tiles nothing else holds
(reference count 1: no other particle, nor the map the worker tracks against), and the
worker's particles still hold theirs: the two never write the same tile, nor one that
the other reads. The cells are those of one process's update, to the bit: each
particle's update is its own.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from fastslam.filter.tiles import TileMaps

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


class Loan(NamedTuple):
    """Tile ids lent for the update of particles first..stop-1 (top: the pool's before)."""

    first: int
    stop: int
    ids: NDArray[np.int32]
    top: int


class OutOfTiles(Exception):
    """The worker needed more tiles than it was lent (then the filter writes its particles)."""


def reach_tiles(maps: TileMaps, origins: NDArray[np.float64], reach: float) -> int:
    """How many tiles of one particle's table an update can write: those of the box of
    every origin (N, 2) within reach [m], inside the table."""
    res, (ty, tx), (oy, ox) = maps.resolution, maps.tile, maps.offset
    _, th, tw = maps.table.shape
    lo = np.floor((origins.min(axis=0) - reach - maps.origin) / res).astype(np.int64)
    hi = np.floor((origins.max(axis=0) + reach - maps.origin) / res).astype(np.int64)
    rows = min(th, (int(hi[1]) + oy) // ty + 1) - max(0, (int(lo[1]) + oy) // ty)
    cols = min(tw, (int(hi[0]) + ox) // tx + 1) - max(0, (int(lo[0]) + ox) // tx)
    return max(rows, 0) * max(cols, 0)


def lend(maps: TileMaps, first: int, stop: int, per_particle: int, bound: int) -> Loan:
    """Lends ids for per_particle tiles of each particle first..stop-1, and makes room in
    the pool for bound tiles of every other particle (reach_tiles: the filter's own writes
    then never grow the pool while the worker writes into it)."""
    pool = maps.pool
    top = pool.top
    ids = pool.alloc((stop - first) * per_particle)
    pool.reserve_more((maps.particles - (stop - first)) * bound)
    return Loan(first, stop, ids, top)


def repay(maps: TileMaps, loan: Loan, slots: NDArray[np.intp], ids: NDArray[np.int32], used: int) -> None:
    """Takes the worker's answer: its particles' table slots (flat, within their rows) now
    hold the tiles ids; it used the first `used` ids lent."""
    rows = maps.table[loan.first:loan.stop].reshape(-1)   # a view: the rows are contiguous
    old = rows[slots]
    rows[slots] = ids
    maps.pool.release(old)
    _give_back(maps, loan, used)


def refund(maps: TileMaps, loan: Loan) -> None:
    """The worker wrote nothing the filter takes: every id lent goes back."""
    _give_back(maps, loan, 0)


def _give_back(maps: TileMaps, loan: Loan, used: int) -> None:
    pool = maps.pool
    unused = loan.ids[used:]
    if len(unused) == 0:
        return
    pool.refs[unused] = 0
    # ids first handed out by this loan, at the pool's top still: the top goes back down
    # (the memory the pool reports stays what the maps hold)
    fresh = unused[unused >= loan.top]
    if len(fresh) and int(fresh.max()) == pool.top - 1 and len(fresh) == pool.top - int(fresh.min()):
        pool.top = int(fresh.min())
        unused = unused[unused < loan.top]
    pool.push_free(unused[::-1].copy())


class LentPool:
    """The worker's view of the filter's pool: the tiles (shared memory) and the ids lent."""

    def __init__(self, tiles: NDArray[np.int8], ids: NDArray[np.int32]) -> None:
        self.tiles = tiles
        self.tile = (int(tiles.shape[1]), int(tiles.shape[2]))
        self.tile_bytes = self.tile[0] * self.tile[1]
        self.ids = ids
        self.used = 0
        self.lent = np.zeros(len(tiles), dtype=bool)
        self.lent[ids] = True

    def alloc(self, k: int) -> NDArray[np.int32]:
        if self.used + k > len(self.ids):
            raise OutOfTiles(f"{self.used + k} tiles needed, {len(self.ids)} lent")
        ids = self.ids[self.used:self.used + k]
        self.used += k
        return ids


class LentMaps(TileMaps):
    """Maps whose every write goes to a lent tile: a copy of the tile the first time."""

    pool: LentPool   # type: ignore[assignment]

    def _writable(self, slots: NDArray[np.intp], *, keep: bool = True) -> NDArray[np.int32]:
        flat = self.table.reshape(-1)
        ids = flat[slots]
        copy = ~self.pool.lent[ids]
        if not copy.any():
            return ids
        new = self.pool.alloc(int(np.count_nonzero(copy)))
        if keep:
            tiles = self.pool.tiles
            tiles[new] = tiles[ids[copy]]          # id 0: zeros
        flat[slots[copy]] = new
        ids[copy] = new
        return ids


def lent_maps(maps: TileMaps, tiles: NDArray[np.int8], ids: NDArray[np.int32]) -> LentMaps:
    """maps (a snapshot's, read from shared tiles) writing into the lent ids."""
    lent = LentMaps.__new__(LentMaps)
    lent.__dict__.update(maps.__dict__)
    lent.pool = LentPool(tiles, ids)
    return lent


def changes(maps: LentMaps) -> tuple[Any, ...]:
    """The worker's answer for repay: (table slots changed, their tiles, ids used). The
    slots changed are those holding a lent tile now: no table held one before."""
    table = maps.table.reshape(-1)
    slots = np.flatnonzero(maps.pool.lent[table])
    return slots, table[slots], maps.pool.used
