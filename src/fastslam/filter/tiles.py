"""Tiled maps: the particles' grids are tables of references to shared tiles.

The lattice of a grid is cut into tiles of TILE cells (rows x columns, powers of two),
fixed in world coordinates: cell (iy, ix) lies in tile row (iy + offset_y) >> log2(rows).
Each particle's map is a table (N, TH, TW) of int32 tile ids into one pool of tiles;
id 0 is the tile never observed (all unknown), shared by every table and never
written, so a grid costs nothing for what nobody has seen. A tile is written in place
only by the one particle that holds it (its reference count is 1); a particle that
writes into a tile it shares (or into id 0) gets a copy first (copy-on-write). So
resampling copies table rows (references), growth re-indexes the tables (new rows and
columns of id 0), and memory follows what was seen and how far the particles' maps
differ, not particles x area.

Tiles freed by resampling (no table refers to them any more) are reused; the pool is
an anonymous memory map grown in place (mremap), whose pages cost memory only once a
tile is used.

The ray tracer reads and writes a box of cells of a few particles at a time through
a CellSpace: either a dense copy of the box (TilePatch: the tiles copied in, the
changed ones written back through copy-on-write at close), when the beams visit
most of it; or the tiles themselves, each index translated to its tile (TileLookup),
when they visit a small part of it (long, sparse beams).
"""
from __future__ import annotations

import math
import mmap
import os
import weakref
from typing import TYPE_CHECKING, Any

import numpy as np

from fastslam.filter.grid import FEW_CELLS, LOGODDS_DTYPE, CellSpace, GridMaps, _read_only
from fastslam.filter.scratch import scratch

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import ArrayLike, NDArray


TILE = (64, 64)        # rows, columns of a tile (powers of two); see docs/benchmarks.md, "Maps"
# A box the beams visit densely is copied (TilePatch) when its cells are at most this
# many times the cells traced; else each index is translated to its tile (TileLookup).
# Measured (docs/benchmarks.md, "Patch or lookup"): the speed suite's boxes hold 1.4-9x
# their traced cells and run up to 2x faster as patches; the Intel log's (real.yaml's
# 20 m beams in a wide box) hold 70-90x and are faster, and 45 MB smaller, as lookups.
PATCH_FACTOR = 16.0


class TilePool:
    """Tiles (T, rows, columns) int8 with reference counts and a free list; id 0 is
    the unknown tile (zeros, never written, never freed).

    shared: the tiles live in a memory file (memfd) that another process can map and read
    (SharedTiles: filter/pipeline.py's tracker), not in private memory.
    """

    def __init__(self, tile: tuple[int, int], capacity: int = 1024, *, shared: bool = False) -> None:
        self.tile = (int(tile[0]), int(tile[1]))
        self.tile_bytes = self.tile[0] * self.tile[1]
        self.capacity = 0
        self.shared = shared
        self.fd = -1              # shared: the memory file, open while the pool lives
        self._map: mmap.mmap | None = None
        self.tiles: NDArray[np.int8] = np.zeros((0,) + self.tile, dtype=LOGODDS_DTYPE)
        self.refs = np.zeros(0, dtype=np.int32)
        self.top = 1             # ids below have been handed out at least once (0: unknown)
        self._free = np.zeros(0, dtype=np.int32)
        self._nfree = 0
        self._reserve(max(int(capacity), 2))

    @property
    def used(self) -> int:
        """Tiles held by some table (id 0 not counted)."""
        return self.top - 1 - self._nfree

    def _reserve(self, capacity: int) -> None:
        """Room for capacity tiles: the memory map grows in place (the kernel moves its
        pages, nothing is copied); untouched pages take no memory."""
        size = capacity * self.tile_bytes
        self.tiles = np.zeros((0,) + self.tile, dtype=LOGODDS_DTYPE)   # drops the view of the old map
        if self._map is None:
            self._map = self._memory(size)
        else:
            try:
                self._map.resize(size)   # (a memory file: grown with it)
            except (BufferError, OSError, SystemError):
                # a view of the tiles is still alive somewhere (or no mremap): copy instead
                grown = self._memory(size)
                grown[:len(self._map)] = self._map[:]
                self._map = grown
        self.tiles = np.frombuffer(self._map, dtype=LOGODDS_DTYPE).reshape((capacity,) + self.tile)
        refs = np.zeros(capacity, dtype=np.int32)
        refs[:len(self.refs)] = self.refs
        self.refs = refs
        self.capacity = capacity

    def _memory(self, size: int) -> mmap.mmap:
        """size bytes of zeros: private, or (shared) a new memory file's."""
        if not self.shared:
            return _anonymous(size)
        fd = os.memfd_create("assign5-tiles", os.MFD_CLOEXEC)
        weakref.finalize(self, os.close, fd)
        os.ftruncate(fd, size)
        self.fd = fd
        return mmap.mmap(fd, size, flags=mmap.MAP_SHARED)

    def alloc(self, k: int) -> NDArray[np.int32]:
        """k tile ids with reference count 1, contents undefined: the free ones first."""
        take = min(k, self._nfree)
        ids = self._free[self._nfree - take:self._nfree][::-1].copy()
        self._nfree -= take
        rest = k - take
        if rest:
            if self.top + rest > self.capacity:
                self._reserve(max(self.top + rest, 2 * self.capacity))
            ids = np.concatenate([ids, np.arange(self.top, self.top + rest, dtype=np.int32)])
            self.top += rest
        self.refs[ids] = 1
        return ids

    def reserve_more(self, k: int) -> None:
        """Room for k more tiles than the free ones without growing (filter/loan.py)."""
        need = self.top + max(0, int(k) - self._nfree)
        if need > self.capacity:
            self._reserve(max(need, 2 * self.capacity))

    def release(self, ids: NDArray[np.integer[Any]]) -> None:
        """Drops one reference of each of ids (repeats count, id 0 ignored); tiles left
        without any go to the free list."""
        ids = ids[ids != 0]
        if len(ids) == 0:
            return
        counts = np.bincount(ids, minlength=self.top)
        hit = np.flatnonzero(counts)
        self.refs[hit] -= counts[hit].astype(np.int32)
        self.push_free(hit[self.refs[hit] == 0].astype(np.int32))

    def hold(self, ids: NDArray[np.integer[Any]]) -> None:
        """Adds one reference to each of ids (repeats count, id 0 ignored)."""
        ids = ids[ids != 0]
        if len(ids):
            counts = np.bincount(ids, minlength=self.top)
            hit = np.flatnonzero(counts)
            self.refs[hit] += counts[hit].astype(np.int32)

    def push_free(self, ids: NDArray[np.int32]) -> None:
        if len(ids) == 0:
            return
        need = self._nfree + len(ids)
        if need > len(self._free):
            grown = np.zeros(max(need, 2 * len(self._free)), dtype=np.int32)
            grown[:self._nfree] = self._free[:self._nfree]
            self._free = grown
        self._free[self._nfree:need] = ids
        self._nfree = need

    def free_ids(self) -> NDArray[np.int32]:
        """The ids in the free list (a copy)."""
        return self._free[:self._nfree].copy()

    @property
    def nbytes(self) -> int:
        """Memory the tiles and their counts take: tiles handed out at least once (a
        free one is reused before a new one is touched)."""
        return self.top * self.tile_bytes + int(self.refs.nbytes) + int(self._free.nbytes)


def snapshot(maps: GridMaps) -> dict[str, Any]:
    """What another process needs to read maps (a view of TileMaps, its pool shared)
    through SharedTiles: the geometry, a copy of the tables, and where the tiles are."""
    if not isinstance(maps, TileMaps) or not maps.pool.shared or maps.pool.fd < 0:
        raise ValueError("the maps' tiles are not shared (TileMaps(..., shared=True))")
    pool = maps.pool
    state = {k: v for k, v in maps.__dict__.items() if k != "pool"}
    state["table"] = maps.table.copy()
    state["origin"] = maps.origin.copy()
    return {"maps": state, "tiles": (os.getpid(), pool.fd, os.fstat(pool.fd).st_ino, pool.capacity, pool.tile)}


class SharedTiles:
    """Another process's shared TilePool: the tiles a snapshot's maps read (writable: the
    tiles lent to this process are written too, filter/loan.py)."""

    def __init__(self, *, writable: bool = False) -> None:
        self.tiles: NDArray[np.int8] = np.zeros((0, 1, 1), dtype=LOGODDS_DTYPE)
        self._key: tuple[int, int, int] | None = None
        self._map: mmap.mmap | None = None
        self._writable = writable

    def maps(self, snap: dict[str, Any]) -> TileMaps:
        """The maps of a snapshot, reading the tiles where they are now."""
        pid, fd, inode, capacity, tile = snap["tiles"]
        size = int(capacity) * int(tile[0]) * int(tile[1])
        if self._key != (pid, fd, inode) or self._map is None or len(self._map) < size:
            mode, prot = ("r+b", mmap.PROT_READ | mmap.PROT_WRITE) if self._writable else ("rb", mmap.PROT_READ)
            with open(f"/proc/{pid}/fd/{fd}", mode) as f:   # the same memory file, opened again
                if os.fstat(f.fileno()).st_ino != inode:
                    raise OSError(f"the tiles' memory file of process {pid} is gone")
                self._map = mmap.mmap(f.fileno(), size, flags=mmap.MAP_SHARED, prot=prot)
            self._key = (pid, fd, inode)
        self.tiles = np.frombuffer(self._map, dtype=LOGODDS_DTYPE, count=size).reshape((-1,) + tuple(tile))
        some = TileMaps.__new__(TileMaps)
        some.__dict__.update(snap["maps"])
        some.pool = self   # type: ignore[assignment]   # reads use pool.tiles only
        return some


def _anonymous(size: int) -> mmap.mmap:
    """Private anonymous memory (a shared one would not grow with resize)."""
    return mmap.mmap(-1, size, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)


class TileMaps(GridMaps):
    """N log-odds grids as tables of shared copy-on-write tiles (see the module doc);
    the same API, geometry and growth as the dense GridMaps, cell for cell.

    Args:
        n, shape, resolution, origin, l_limit: as GridMaps.
        tile: (rows, columns) of a tile, powers of two.
        shared: the tiles in a memory file other processes can read (TilePool).
    """

    def __init__(self, n: int, shape: tuple[int, int], resolution: float,
                 origin: tuple[float, float], l_limit: float = 5.0, *, tile: tuple[int, int] = TILE,
                 shared: bool = False) -> None:
        self._init_geometry(n, shape, resolution, origin, l_limit)
        ty, tx = int(tile[0]), int(tile[1])
        if ty < 1 or tx < 1 or ty & (ty - 1) or tx & (tx - 1):
            raise ValueError(f"tile sides must be powers of two, got {tile}")
        self.tile = (ty, tx)
        self._ly, self._lx = ty.bit_length() - 1, tx.bit_length() - 1   # log2 of the sides
        self.offset = (0, 0)   # cell (iy, ix) is lattice cell (iy + offset[0], ix + offset[1])
        h, w = self.shape
        self.table = np.zeros((n, -(-h // ty), -(-w // tx)), dtype=np.int32)
        self.pool = TilePool(self.tile, shared=shared)

    # -- memory -----------------------------------------------------------------------
    @staticmethod
    def bytes_for(n: int, shape: tuple[int, int], tile: tuple[int, int] = TILE) -> int:
        """Bytes n fresh maps of shape (H, W) take: their tables (no tile is held)."""
        return int(n) * -(-int(shape[0]) // tile[0]) * -(-int(shape[1]) // tile[1]) * 4

    @property
    def nbytes(self) -> int:
        """Bytes the maps hold now: the tiles used so far and the tables."""
        return self.pool.nbytes + int(self.table.nbytes)

    def growth_bytes(self, xmin: float, ymin: float, xmax: float, ymax: float, *, fraction: float = 0.5) -> int:
        """Bytes grow_to with these arguments allocates: the grown tables (the old ones
        are freed after the copy; no tile is allocated), 0 when the box is covered."""
        if self.covers(xmin, ymin, xmax, ymax):
            return 0
        left, right, down, up = self._padding(xmin, ymin, xmax, ymax, fraction)
        return self.particles * int(np.prod(self._grown_table(left, right, down, up)[2])) * 4

    # -- geometry of the lattice ------------------------------------------------------
    def _grown_table(self, left: int, right: int, down: int, up: int
                     ) -> tuple[tuple[int, int], tuple[int, int], tuple[int, int]]:
        """(tile rows, columns added below and left), (new offset), (new table shape)."""
        (ty, tx), (oy, ox) = self.tile, self.offset
        h, w = self.shape
        add_y = -(-(down - oy) // ty) if down > oy else 0
        add_x = -(-(left - ox) // tx) if left > ox else 0
        noy, nox = oy + add_y * ty - down, ox + add_x * tx - left
        th = max(-(-(noy + h + down + up) // ty), add_y + self.table.shape[1])
        tw = max(-(-(nox + w + left + right) // tx), add_x + self.table.shape[2])
        return (add_y, add_x), (noy, nox), (th, tw)

    def _grow_storage(self, left: int, right: int, down: int, up: int) -> None:
        (add_y, add_x), offset, shape = self._grown_table(left, right, down, up)
        n, th, tw = self.table.shape
        table = np.zeros((n,) + shape, dtype=np.int32)
        table[:, add_y:add_y + th, add_x:add_x + tw] = self.table
        self.table, self.offset = table, offset

    def _slots(self, n: NDArray[np.intp], ly: NDArray[np.intp], lx: NDArray[np.intp]) -> NDArray[np.intp]:
        """Flat table index of the tiles of lattice cells (ly, lx) of particles n."""
        _, th, tw = self.table.shape
        return (n * th + (ly >> self._ly)) * tw + (lx >> self._lx)

    def _positions(self, ids: NDArray[np.integer[Any]], ly: NDArray[np.intp], lx: NDArray[np.intp]
                   ) -> NDArray[np.intp]:
        """Flat pool index of lattice cells (ly, lx) in tiles ids."""
        ty, tx = self.tile
        return (ids.astype(np.intp) << (self._ly + self._lx)) | ((ly & (ty - 1)) << self._lx) | (lx & (tx - 1))

    def _lattice(self, n: ArrayLike, iy: ArrayLike, ix: ArrayLike
                 ) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
        n_, iy_, ix_ = np.broadcast_arrays(np.asarray(n, dtype=np.intp), np.asarray(iy, dtype=np.intp),
                                           np.asarray(ix, dtype=np.intp))
        return n_, iy_ + self.offset[0], ix_ + self.offset[1]

    # -- cells ------------------------------------------------------------------------
    def values(self, n: ArrayLike, iy: ArrayLike, ix: ArrayLike) -> NDArray[np.int8]:
        """As GridMaps.values."""
        n_, ly, lx = self._lattice(n, iy, ix)
        ids = self.table.reshape(-1).take(self._slots(n_, ly, lx))
        return self.pool.tiles.reshape(-1).take(self._positions(ids, ly, lx))

    def values_around(self, n: ArrayLike, iy: ArrayLike, ix: ArrayLike, dy: ArrayLike, dx: ArrayLike, *,
                      out: NDArray[np.int8] | None = None) -> NDArray[np.int8]:
        """As GridMaps.values_around. Each point's cells are its own cell's position plus
        the offset within its tile; only points whose kernel leaves their tile (near
        its edges) are looked up cell by cell."""
        (ty, tx), (oy, ox), (sy, sx) = self.tile, self.offset, (self._ly, self._lx)
        _, th, tw = self.table.shape
        dy_, dx_ = np.asarray(dy, dtype=np.intp), np.asarray(dx, dtype=np.intp)
        n_, iy_, ix_ = np.asarray(n, dtype=np.intp), np.asarray(iy), np.asarray(ix)
        shape = np.broadcast(n_, iy_, ix_).shape
        # lattice cells of the points (written into full-shape arrays: no broadcast_to,
        # whose Python cost is most of a small call's)
        ly = np.add(iy_, oy, out=np.empty(shape, dtype=np.intp), dtype=np.intp)
        lx = np.add(ix_, ox, out=np.empty(shape, dtype=np.intp), dtype=np.intp)
        if ly.size * len(dy_) <= FEW_CELLS:   # few cells: each one's tile looked up, in fewer calls
            ey = ly + dy_.reshape((-1,) + (1,) * ly.ndim)                            # (K,) + shape
            ex = lx + dx_.reshape((-1,) + (1,) * lx.ndim)
            slot = ey >> sy
            slot *= tw
            slot += ex >> sx
            slot += n_ * (th * tw)
            pos = self.table.reshape(-1).take(slot).astype(np.intp)
            pos <<= sy + sx
            ey &= ty - 1
            ey <<= sx
            pos |= ey
            ex &= tx - 1
            pos |= ex
            return self.pool.tiles.reshape(-1).take(pos, out=out)
        slot = ly >> sy
        slot *= tw
        slot += lx >> sx
        slot += n_ * (th * tw)
        base = self.table.reshape(-1).take(slot).astype(np.intp)      # pool position of each point's cell
        base <<= sy + sx
        ry, rx = ly & (ty - 1), lx & (tx - 1)
        base |= ry << sx
        base |= rx
        dys, dxs = dy_.tolist(), dx_.tolist()
        inner = ry >= -min(dys)
        inner &= ry < ty - max(dys)
        inner &= rx >= -min(dxs)
        inner &= rx < tx - max(dxs)
        pos = base[None] + (dy_ * tx + dx_).reshape((-1,) + (1,) * base.ndim)      # (K,) + shape
        edge = np.flatnonzero(~inner)
        if len(edge):
            ey = ly.reshape(-1)[edge] + dy_[:, None]                                # (K, E)
            ex = lx.reshape(-1)[edge] + dx_[:, None]
            n_edge = (n_ if n_.shape == shape else np.broadcast_to(n_, shape)).reshape(-1)[edge]
            ids = self.table.reshape(-1).take(self._slots(n_edge, ey, ex))
            pos.reshape(len(dy_), -1)[:, edge] = self._positions(ids, ey, ex)
        return self.pool.tiles.reshape(-1).take(pos, out=out)

    def particle_map(self, n: int) -> NDArray[np.int8]:
        """(H, W) particle n's map (a copy), read only."""
        h, w = self.shape
        return self.crop(0, h, 0, w, n, n + 1)[0]

    def crop(self, y0: int, y1: int, x0: int, x1: int, first: int = 0, stop: int | None = None) -> NDArray[np.int8]:
        """As GridMaps.crop (a copy)."""
        stop = self.particles if stop is None else stop
        (ty, tx), (oy, ox) = self.tile, self.offset
        r0, c0 = (y0 + oy) >> self._ly, (x0 + ox) >> self._lx
        r1, c1 = ((y1 - 1 + oy) >> self._ly) + 1, ((x1 - 1 + ox) >> self._lx) + 1
        out = self._gather(self.table[first:stop, r0:r1, c0:c1])
        k, nr, _, nc, _ = out.shape
        sy, sx = y0 + oy - r0 * ty, x0 + ox - c0 * tx
        return _read_only(out.reshape(k, nr * ty, nc * tx)[:, sy:sy + y1 - y0, sx:sx + x1 - x0])

    def _gather(self, ids: NDArray[np.int32], out: NDArray[np.int8] | None = None) -> NDArray[np.int8]:
        """(k, nr, rows, nc, columns) the tiles ids (k, nr, nc) laid out as dense rows: one
        gather of tile rows (a row of a tile is contiguous in the pool)."""
        ty, tx = self.tile
        rows = ids[:, :, None, :].astype(np.intp) * ty + np.arange(ty)[:, None]         # (k, nr, rows, nc)
        return np.take(self.pool.tiles.reshape(-1, tx), rows, axis=0, out=out)

    def put(self, n: ArrayLike, iy: ArrayLike, ix: ArrayLike, values: ArrayLike) -> None:
        """As GridMaps.put: the tiles written become the particles' own first."""
        n_, ly, lx = self._lattice(n, iy, ix)
        slots = self._slots(n_, ly, lx).reshape(-1)
        self._writable(np.unique(slots))
        ids = self.table.reshape(-1).take(slots)
        tiles = self.pool.tiles.reshape(-1)
        tiles[self._positions(ids, ly.reshape(-1), lx.reshape(-1))] = np.broadcast_to(values, n_.shape).reshape(-1)

    def copy(self) -> GridMaps:
        """Independent maps with the same cells and geometry (their own tiles)."""
        other = TileMaps.__new__(TileMaps)
        other.__dict__.update(self.__dict__)
        other.origin, other.table = self.origin.copy(), self.table.copy()
        pool = other.pool = TilePool(self.tile, self.pool.capacity)
        pool.tiles[:self.pool.top] = self.pool.tiles[:self.pool.top]
        pool.refs[:] = self.pool.refs
        pool.top = self.pool.top
        pool.push_free(self.pool.free_ids())
        return other

    def view(self, first: int, stop: int | None = None) -> TileMaps:
        """As GridMaps.view: the particles' tables (a view) over the same tiles, for reads."""
        stop = first + 1 if stop is None else stop
        some = TileMaps.__new__(TileMaps)
        some.__dict__.update(self.__dict__)
        some.particles, some.origin = stop - first, self.origin.copy()
        some.table = self.table[first:stop]
        return some

    def frozen(self, n: int) -> TileMaps:
        """Particle n's map as it is now, for reads: its table copied, the tiles shared (they
        stay as they are while held: TilePool.hold)."""
        some = self.view(n)
        some.table = some.table.copy()
        return some

    def cells(self, first: int, stop: int, lo: tuple[int, int] | None = None, hi: tuple[int, int] | None = None,
              *, traced: int = 0) -> CellSpace:
        """As GridMaps.cells: a TilePatch when the box holds at most PATCH_FACTOR times
        the cells traced (or traced is 0), else a TileLookup."""
        h, w = self.shape
        lo = (0, 0) if lo is None else lo
        hi = (w, h) if hi is None else hi
        oy, ox = self.offset
        r0, c0 = (lo[1] + oy) >> self._ly, (lo[0] + ox) >> self._lx
        r1 = ((max(hi[1], lo[1] + 1) - 1 + oy) >> self._ly) + 1
        c1 = ((max(hi[0], lo[0] + 1) - 1 + ox) >> self._lx) + 1
        box = (stop - first) * (r1 - r0) * (c1 - c0) * self.pool.tile_bytes
        if traced <= 0 or box <= PATCH_FACTOR * traced:
            return TilePatch(self, first, stop, (r0, r1, c0, c1))
        return TileLookup(self, first, stop, (r0, r1, c0, c1))

    def clear(self) -> None:
        """Every map back to unknown: the tables' tiles released (a tile something else
        holds, as the tracked map, stays until it lets go), the tables all id 0."""
        self.pool.release(self.table.reshape(-1))
        self.table.fill(0)

    def reorder(self, parent: NDArray[np.intp]) -> None:
        """Slot s takes the map of slot parent[s]: table rows copied, tiles shared."""
        moved = np.flatnonzero(parent != np.arange(len(parent)))
        if len(moved) == 0:
            return
        rows = self.table[parent[moved]]          # every source read first
        self.pool.hold(rows.reshape(-1))
        self.pool.release(self.table[moved].reshape(-1))
        self.table[moved] = rows

    def known_cells(self) -> NDArray[np.int64]:
        """(N,) number of cells each particle has observed."""
        pool = self.pool
        counts = np.count_nonzero(pool.tiles[:pool.top].reshape(pool.top, -1), axis=1)
        return np.asarray(counts[self.table].reshape(self.particles, -1).sum(axis=1), dtype=np.int64)

    # -- copy-on-write ----------------------------------------------------------------
    def _writable(self, slots: NDArray[np.intp], *, keep: bool = True) -> NDArray[np.int32]:
        """Makes the tiles at the (distinct) table slots their particle's own, a copy for
        each one shared or unknown (keep=False: a new tile, contents undefined, for one
        about to be overwritten whole); returns their ids."""
        flat = self.table.reshape(-1)
        ids = flat[slots]
        pool = self.pool
        copy = (ids == 0) | (pool.refs[ids] > 1)
        shared = np.flatnonzero(copy & (ids != 0))
        if len(shared):
            # a tile whose every holder writes now stays with the first of them
            held = ids[shared]
            count = np.bincount(held, minlength=pool.top)
            first = np.empty(pool.top, dtype=np.intp)
            first[held[::-1]] = shared[::-1]              # repeats: the last write, the first slot, wins
            alone = np.flatnonzero(count[held] == pool.refs[held])
            copy[first[held[alone]]] = False
        if not copy.any():
            return ids
        old = ids[copy]
        new = pool.alloc(len(old))
        if keep:
            tiles = pool.tiles
            tiles[new] = tiles[old]                # id 0: zeros
        drop = old[old != 0]
        if len(drop):
            np.subtract.at(pool.refs, drop, 1)     # never to 0: shared by more than the writers
        flat[slots[copy]] = new
        ids[copy] = new
        return ids


class TilePatch(CellSpace):
    """A dense copy of tile rows r0..r1-1, columns c0..c1-1 of particles first..stop-1;
    close() writes the tiles that changed back (copy-on-write)."""

    def __init__(self, maps: TileMaps, first: int, stop: int, box: tuple[int, int, int, int]) -> None:
        r0, r1, c0, c1 = box
        (ty, tx), (oy, ox) = maps.tile, maps.offset
        self.maps, self.first, self.box = maps, first, box
        k, nr, nc = stop - first, r1 - r0, c1 - c0
        shape = (k, nr, ty, nc, tx)
        self.dense = maps._gather(maps.table[first:stop, r0:r1, c0:c1], scratch("tile_patch", shape, LOGODDS_DTYPE))
        self.before = scratch("tile_patch_before", shape, LOGODDS_DTYPE)
        np.copyto(self.before, self.dense)
        super().__init__(maps, self.dense.reshape(-1), rows=nr * ty, stride=nc * tx, y0=r0 * ty - oy,
                         x0=c0 * tx - ox, lead=0, size=self.dense.size)

    def close(self) -> None:
        maps = self.maps
        k, nr, ty, nc, tx = self.dense.shape
        i, r, c = np.nonzero(_changed_tiles(self.dense, self.before))
        if len(i) == 0:
            return
        r0, _, c0, _ = self.box
        _, th, tw = maps.table.shape
        # a changed tile is written whole: a new one needs no copy of the old cells
        ids = maps._writable((((self.first + i) * th + r0 + r) * tw + c0 + c).astype(np.intp), keep=False)
        # a take of tile rows, then whole tiles: several times faster than dense[i, r, :, c]
        src = (((i * nr + r)[:, None] * ty + np.arange(ty)) * nc + c[:, None]).astype(np.intp)
        maps.pool.tiles[ids.astype(np.intp)] = np.take(self.dense.reshape(-1, tx), src, axis=0)


def _changed_tiles(dense: NDArray[np.int8], before: NDArray[np.int8]) -> NDArray[np.bool_]:
    """(k, nr, nc) whether each tile of dense (k, nr, rows, nc, columns) differs from before."""
    k, nr, ty, nc, tx = dense.shape
    if tx % 8 or tx > 64:
        return np.asarray((dense != before).any(axis=(2, 4)))
    # 8 cells at a time, then the (at most 8) flags of a row of a tile as one integer
    differ = np.not_equal(dense.view(np.uint64), before.view(np.uint64),
                          out=scratch("tile_differ", dense.shape[:4] + (tx // 8,), np.bool_))
    row = differ.view({1: np.uint8, 2: np.uint16, 4: np.uint32, 8: np.uint64}[tx // 8])[..., 0]   # (k, nr, rows, nc)
    return np.asarray(np.ascontiguousarray(row.transpose(0, 1, 3, 2)).any(axis=3))


class TileLookup(CellSpace):
    """Tile rows r0..r1-1, columns c0..c1-1 of particles first..stop-1 addressed in
    place: an index's tile comes from a small table of the box (a power-of-two stride
    splits the index into tile and cell with shifts)."""

    def __init__(self, maps: TileMaps, first: int, stop: int, box: tuple[int, int, int, int]) -> None:
        r0, r1, c0, c1 = box
        (ty, tx), (oy, ox) = maps.tile, maps.offset
        self.maps, self.first, self.box = maps, first, box
        k, nr, nc = stop - first, r1 - r0, c1 - c0
        self._bits = max(int(math.ceil(math.log2(nc * tx))), maps._lx)      # stride 2**bits
        cols = 1 << (self._bits - maps._lx)
        self.ids = np.zeros((k, nr, cols), dtype=np.int32)
        self.ids[:, :, :nc] = maps.table[first:stop, r0:r1, c0:c1]
        self._start = self.ids.astype(np.intp) << (maps._ly + maps._lx)      # pool position of each tile
        # no view of the tiles is kept: writable may move them (see values)
        super().__init__(maps, np.zeros(0, dtype=LOGODDS_DTYPE), rows=nr * ty, stride=1 << self._bits,
                         y0=r0 * ty - oy, x0=c0 * tx - ox, lead=0, size=k * nr * ty << self._bits)
        self.write_type = self.index_type   # the translation is cheaper on narrow indices

    @property
    def values(self) -> NDArray[np.int8]:
        """The tiles, read afresh (writable may have moved them)."""
        return self.maps.pool.tiles.reshape(-1)

    def _split(self, flat: NDArray[np.integer[Any]]) -> tuple[NDArray[np.integer[Any]], NDArray[np.integer[Any]]]:
        """(index into self.ids of each index's tile, position of its cell in the tile)."""
        b, lx, ly = self._bits, self.maps._lx, self.maps._ly
        ty, tx = self.maps.tile
        q = flat >> lx                                   # (row, tile column)
        slot = q >> (b - lx + ly)                        # tile row
        slot <<= b - lx
        slot |= q & ((1 << (b - lx)) - 1)
        q >>= b - lx                                     # row
        q &= ty - 1
        q <<= lx
        q |= flat & (tx - 1)
        return slot, q

    def _positions(self, slot: NDArray[np.integer[Any]], within: NDArray[np.integer[Any]]) -> NDArray[np.intp]:
        pos = self._start.reshape(-1).take(slot)
        pos |= within
        return pos

    def resolve(self, flat: NDArray[np.integer[Any]]) -> NDArray[np.integer[Any]]:
        return self._positions(*self._split(flat))

    def writable(self, flat: NDArray[np.integer[Any]]) -> NDArray[np.integer[Any]]:
        slot, within = self._split(flat)
        slot = slot.astype(np.intp)   # numpy indexes with intp twice as fast as with int32
        touched = np.zeros(self.ids.size, dtype=bool)
        touched[slot] = True
        where = np.flatnonzero(touched)
        k, nr, cols = self.ids.shape
        i, r, c = np.unravel_index(where, (k, nr, cols))
        r0, _, c0, _ = self.box
        _, th, tw = self.maps.table.shape
        ids = self.maps._writable((((self.first + i) * th + r0 + r) * tw + c0 + c).astype(np.intp))
        self.ids.reshape(-1)[where] = ids
        self._start.reshape(-1)[where] = ids.astype(np.intp) << (self.maps._ly + self.maps._lx)
        return self._positions(slot, within)

