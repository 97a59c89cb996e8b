"""The tracker in a second process: the scans between two updates are tracked while the
particles work on the next update (offline: a third of the ACES bag's time is tracking).
The worker also matches some of the particles of each update (match_poses's helper), and
weighs some and writes the scan into their maps (update_trimmed's writer, filter/loan.py),
while the filter does the others: as many as leave both about as busy (the shares).

The worker runs a Tracker (filter/track.py) on the same inputs, so the results are the
same to the bit. It reads the best particle's map from the filter's tiles, shared memory
(TileMaps(shared=True)), as it was at the update: its tiles hold a reference until the
next update (_hold), so the filter's writes copy them rather than write into them.

Each particle's match, weight and map are its own (the search window is the whole set's),
so the shares change no result. The scans go to the worker as they come; the filter waits
only where it needs the pose (the paths' next poses, after the maps are written; an update;
a reset) or the worker's share. If the worker fails or dies, the tracker says why once
(failure) and does its work in this process from then on, the scans since the last wait
first: the same results, slower.
"""
from __future__ import annotations

import multiprocessing
import os
import time
from multiprocessing.connection import Connection
from typing import TYPE_CHECKING, Any

import numpy as np

from fastslam.config import SlamConfig
from fastslam.filter import loan
from fastslam.filter.grid import GridMaps
from fastslam.filter.scan import Scan
from fastslam.filter.tiles import SharedTiles, TileMaps, TilePool, snapshot
from fastslam.filter.track import Tracker
from fastslam.filter.trimmed import write_some
from fastslam.match import MatchParams
from fastslam.match.matcher import match_some

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray

    from fastslam.match.matcher import MatchPart

# Timing estimates (exponential means) start here and follow each update by this much
FIRST_SHARE = 1 / 3    # of the particles handed over before any time is measured
SMOOTHING = 0.2
# Tiles lent per particle for the worker's map writes at first (filter/loan.py); then twice the
# most an update used per particle, and twice as many after the worker ran out (CSAIL: 11 a particle, at most 28)
FIRST_LOAN = 64
# The filter waits for the worker after this many scans without an update (a robot standing
# for an hour would otherwise keep every scan here until it moves)
MAX_QUEUED = 256


def available() -> bool:
    """Whether this machine can run the worker: two cores for this process (its CPU
    affinity, as taskset and containers set it), fork and memory files (Linux)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return cores >= 2 and hasattr(os, "memfd_create") and "fork" in multiprocessing.get_all_start_methods()


class PipelinedTracker(Tracker):
    """A Tracker whose scans between updates are tracked in a worker process (close() ends it)."""

    shares_maps = True

    @property
    def helper(self) -> PipelinedTracker | None:   # type: ignore[override]
        """This tracker matches particles too while its worker lives."""
        return None if self.failure else self

    @property
    def writer(self) -> PipelinedTracker | None:   # type: ignore[override]
        """... and writes the scan into some particles' maps."""
        return None if self.failure else self

    def __init__(self, cfg: SlamConfig, params: MatchParams) -> None:
        self._pose = np.zeros(3)
        self._stalls = 0
        self._queued: list[tuple[Any, ...]] = []   # sent since the last wait: tracked here if the worker fails
        self._tracks = 0                           # ... of them scans
        self.failure = ""                          # why the worker is not used (empty: it is)
        self.served = 0                            # scans the worker tracked
        self.matched = 0                           # particles the worker matched
        self._per_scan = 0.0                       # [s] the worker's tracking of one scan, on average
        self._per_particle = (0.0, 0.0)            # [s] matching one particle here, there, on average
        self._handed: tuple[int, float] | None = None   # particles handed over, when
        self._particles = 0                        # the particles of the last share()
        self._free_at = 0.0                        # [s] when the worker will have tracked what it was sent
        self.wrote = 0                             # particles whose maps the worker wrote
        self._per_write = (0.0, 0.0)               # [s] one particle's map write here, there, on average
        self._loan: tuple[loan.Loan, float] | None = None   # tiles lent for the writes, when
        self._lend = FIRST_LOAN                    # tiles lent per particle
        self.short = 0                             # writes the worker gave back for want of tiles
        self._held: tuple[TilePool, NDArray[np.int32]] | None = None   # tiles of the map it tracks against
        super().__init__(cfg, params)
        ctx = multiprocessing.get_context("fork")
        self._conn, theirs = ctx.Pipe()
        self._worker = ctx.Process(target=_serve, args=(theirs, self._conn, cfg, params), name="assign5-tracker",
                                   daemon=True)
        self._worker.start()
        theirs.close()

    # what the filter reads waits for the worker first
    @property
    def pose(self) -> NDArray[np.float64]:
        self.settle()
        return self._pose

    @pose.setter
    def pose(self, pose: NDArray[np.float64]) -> None:
        self._pose = pose

    @property
    def stalls(self) -> int:
        self.settle()
        return self._stalls

    @stalls.setter
    def stalls(self, count: int) -> None:
        self._stalls = count

    def clear(self) -> None:
        self.settle()
        self._hold(None, 0)
        super().clear()

    def start(self, pose: NDArray[np.float64], odom: NDArray[np.float64], ranges: NDArray[np.float64],
              maps: GridMaps, best: int) -> None:
        self.settle()
        super().start(pose, odom, ranges, maps, best)
        self._hold(maps, best)
        self._send_maps("start", maps.view(best), super().state())

    def _hold(self, maps: GridMaps | None, best: int) -> None:
        """The tiles of the map the worker tracks against hold a reference until the next
        start: the filter's writes meanwhile copy them (and no tile of it is freed), so
        the filter need not wait for the tracking before it writes the scan into its maps.
        A failed worker's scans are tracked here against the same tiles."""
        if self._held is not None:
            pool, ids = self._held
            pool.release(ids)
            self._held = None
        if isinstance(maps, TileMaps) and not self.failure:
            view = maps.frozen(best)   # as at the update, whatever is written
            ids = view.table.reshape(-1)
            maps.pool.hold(ids)
            self._held = (maps.pool, ids)
            self.grid = view   # what this process tracks against if the worker fails

    def track(self, odom: NDArray[np.float64], scan: Scan) -> None:
        if self.failure:
            super().track(odom, scan)
            return
        self._queued.append(("track", odom, scan))
        self._tracks += 1
        self._send(("track", odom, scan))
        self._free_at = max(self._free_at, time.perf_counter()) + self._per_scan
        if len(self._queued) >= MAX_QUEUED:
            self.settle()

    def rebase(self, odom: NDArray[np.float64]) -> None:
        if self.failure:
            super().rebase(odom)
            return
        self._queued.append(("rebase", odom))
        self._send(("rebase", odom))

    def moved(self, odom: NDArray[np.float64]) -> NDArray[np.float64]:
        self.settle()
        return super().moved(odom)

    def ticket(self) -> int:
        return super().ticket() + self._tracks

    def state(self) -> dict[str, Any]:
        self.settle()
        return super().state()

    def settle(self) -> None:
        """Waits for the worker: the poses of the scans sent since the last wait."""
        if not self._queued:
            return
        if not self.failure:
            self._send(("sync",))
        reply = self._receive("state")
        if reply is None:
            self._replay()
            return
        super().load(reply[1])
        if self.timeline is not None:
            self.timeline.extend(reply[2])
        self.served += self._tracks
        if self._tracks:
            self._per_scan = _mean(self._per_scan, reply[3] / self._tracks)
        self._queued, self._tracks = [], 0
        self._free_at = time.perf_counter()   # it has answered everything

    # -- matching some particles (match.matcher.Helper) --------------------------------
    def share(self, n: int) -> int:
        """The particles to hand over (the results do not depend on it)."""
        self._particles = n
        return self._balanced(n, self._per_particle)

    def submit(self, grid: GridMaps, args: tuple[Any, ...], size: int) -> None:
        self._send_maps("match", grid, args, size)
        self._handed = (grid.particles, time.perf_counter())

    def result(self, grid: GridMaps, args: tuple[Any, ...], size: int) -> MatchPart:
        assert self._handed is not None
        handed, since = self._handed
        mine = (time.perf_counter() - since, self._particles - handed)   # the filter matched its own meanwhile
        reply = self._receive("matched")
        if reply is None:
            self._per_particle = self._timed(self._per_particle, mine)
            return match_some(grid, args, size)
        _, part, began, ended = reply
        self._per_particle = self._timed(self._per_particle, mine, (began, ended, handed))
        self.matched += handed
        return part

    # -- writing some particles' maps (trimmed.Writer) ---------------------------------
    def write_share(self, n: int) -> int:
        """The particles the worker weighs and writes."""
        return self._balanced(n, self._per_write)

    def submit_writes(self, grid: GridMaps, first: int, args: tuple[Any, ...], origins: NDArray[np.float64],
                      reach: float) -> None:
        if not isinstance(grid, TileMaps):
            self._fail("the maps cannot be shared (dense maps, not tiles)")
            return
        bound = loan.reach_tiles(grid, origins, reach)
        lent = loan.lend(grid, first, grid.particles, min(self._lend, bound), bound)
        self._loan = (lent, time.perf_counter())
        self._send_maps("write", grid.view(first, grid.particles), lent.ids, args)

    def written(self, grid: GridMaps, first: int, args: tuple[Any, ...]) -> NDArray[np.float64] | None:
        n = grid.particles
        lent, since = self._loan if self._loan is not None else (None, 0.0)
        self._loan = None
        mine = (time.perf_counter() - since, first)   # the filter wrote its own meanwhile
        reply = self._receive("written") if lent is not None else None
        if reply is not None and reply[1] is not None:
            assert isinstance(grid, TileMaps) and lent is not None
            _, slots, ids, used, log_w, began, ended = reply
            loan.repay(grid, lent, slots, ids, used)
            self._per_write = self._timed(self._per_write, mine, (began, ended, n - first))
            self._lend = max(self._lend, 2 * -(-used // (n - first)))
            self.wrote += n - first
            return log_w
        if reply is not None:   # it ran out of tiles
            self.short += 1
            self._lend *= 2
        if lent is not None:
            assert isinstance(grid, TileMaps)
            loan.refund(grid, lent)
        self._per_write = self._timed(self._per_write, mine)
        return write_some(grid.view(first, n), args)

    # -- the shares' balance -------------------------------------------------------------
    def _balanced(self, n: int, per: tuple[float, float]) -> int:
        """Of n particles, the worker's share: as many as leave it, after the scans it still
        has to track, as busy as this process (per: one particle's time here, there)."""
        if self.failure or n < 2:
            return 0
        here, there = per
        if here <= 0 or there <= 0:
            return int(n * FIRST_SHARE)
        backlog = max(0.0, self._free_at - time.perf_counter())
        return int(np.clip(round((n * here - backlog) / (here + there)), 0, n - 1))

    def _timed(self, per: tuple[float, float], mine: tuple[float, int],
               theirs: tuple[float, float, int] | None = None) -> tuple[float, float]:
        """per followed by a share's times: this process's (seconds, particles), the worker's
        from its start to its end (its answer: it has nothing left)."""
        here, there = per
        seconds, kept = mine
        if kept > 0:
            here = _mean(here, seconds / kept)
        if theirs is not None:
            began, ended, handed = theirs
            there = _mean(there, (ended - began) / handed)
            self._free_at = time.perf_counter()
        return here, there

    def close(self) -> None:
        """Ends the worker; what it was sent since the last wait is dropped (settle first to keep it)."""
        if self._worker.is_alive():
            try:
                self._conn.send(("stop",))
            except OSError:
                pass
            self._worker.join(timeout=5)
            if self._worker.is_alive():
                self._worker.terminate()
                self._worker.join()
        self._conn.close()
        self.failure = self.failure or "closed"
        self._hold(None, 0)

    def _send_maps(self, kind: str, maps: GridMaps, *rest: Any) -> None:
        """A message (kind, the maps' snapshot, *rest); maps that cannot be shared end the worker's use."""
        if self.failure:
            return
        try:
            snap = snapshot(maps)
        except (ValueError, OSError) as err:
            self._fail(f"the maps cannot be shared ({err})")
            return
        self._send((kind, snap, *rest))

    def _receive(self, kind: str) -> tuple[Any, ...] | None:
        """The worker's next reply, of this kind; None if it failed (then given up)."""
        if self.failure:
            return None
        try:
            reply: tuple[Any, ...] = self._conn.recv()
        except (EOFError, OSError) as err:
            reply = ("error", self._why(err))
        if reply[0] == kind:
            return reply
        self._fail(f"the tracking process failed ({reply[1]})")
        return None

    def _send(self, message: tuple[Any, ...]) -> None:
        try:
            self._conn.send(message)
        except OSError as err:   # the worker is gone: what it was sent is tracked here at the next wait
            self._fail(f"the tracking process is gone ({self._why(err)})")

    def _why(self, err: BaseException) -> str:
        """The worker's own report of its failure if it left one, else err."""
        try:
            while self._conn.poll():
                reply = self._conn.recv()
                if reply[0] == "error":
                    return str(reply[1])
        except (EOFError, OSError):
            pass
        return f"{type(err).__name__}: {err}"

    def _fail(self, why: str) -> None:
        if not self.failure:
            self.failure = why
        if self._worker.is_alive():
            self._worker.terminate()

    def _replay(self) -> None:
        """The scans the worker did not give back, tracked here."""
        queued, self._queued, self._tracks = self._queued, [], 0
        for message in queued:
            if message[0] == "track":
                super().track(message[1], message[2])
            else:
                super().rebase(message[1])


def _serve(conn: Connection, filters_end: Connection, cfg: SlamConfig, params: MatchParams) -> None:
    """The worker: a Tracker fed by conn's messages, in order."""
    filters_end.close()   # so that the filter's end of the pipe closing ends this one
    tracker = Tracker(cfg, params)
    tracker.timeline = []
    tiles = SharedTiles()
    writable = SharedTiles(writable=True)   # the tiles lent for the writes
    busy = 0.0   # [s] tracking since the last sync
    try:
        while True:
            message = conn.recv()
            kind = message[0]
            if kind == "track":
                began = time.perf_counter()
                tracker.track(message[1], message[2])
                busy += time.perf_counter() - began
            elif kind == "rebase":
                tracker.rebase(message[1])
            elif kind == "start":
                tracker.grid = tiles.maps(message[1])
                tracker.load(message[2])
            elif kind == "sync":
                conn.send(("state", tracker.state(), tracker.timeline, busy))
                tracker.timeline, busy = [], 0.0
            elif kind == "match":
                began = time.perf_counter()
                part = match_some(tiles.maps(message[1]), message[2], message[3])
                conn.send(("matched", part, began, time.perf_counter()))
            elif kind == "write":
                conn.send(_write(writable, *message[1:]))
            else:
                return
    except (EOFError, KeyboardInterrupt, BrokenPipeError):
        return
    except Exception as err:  # reported to the filter, which then tracks in its own process
        try:
            conn.send(("error", f"{type(err).__name__}: {err}"))
        except OSError:
            pass


def _write(tiles: SharedTiles, snap: dict[str, Any], ids: NDArray[np.int32], args: tuple[Any, ...]
           ) -> tuple[Any, ...]:
    """The worker's weights and writes into the tiles lent (loan.py): ("written", slots, ids,
    used, log-weights, when it began and ended)."""
    began = time.perf_counter()
    maps = loan.lent_maps(tiles.maps(snap), tiles.tiles, ids)
    try:
        log_w = write_some(maps, args)
    except loan.OutOfTiles:   # the filter writes them itself
        return ("written", None)
    return ("written", *loan.changes(maps), log_w, began, time.perf_counter())


def _mean(mean: float, value: float) -> float:
    """An exponential mean (the value itself at first)."""
    return value if mean <= 0 else mean + SMOOTHING * (value - mean)
