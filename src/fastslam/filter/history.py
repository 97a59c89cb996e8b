"""The particles' trajectories as an ancestry tree in arrays (gmapping's tree, pruned).

Each processed scan adds the poses of all N particles after resampling and, for each
slot, the slot of the previous scan it descends from. A particle's path is read by
following these parents backwards. Lineages merge within a few resamplings, so the
history is pruned now and then to the steps some living particle descends from, and
the steps all of them share move into one compact block (the trunk): memory grows by
about one pose per update, not N.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


PRUNE_EVERY = 256  # updates between prunings


class History:
    """Poses (t, x, y, theta) of every processed scan, for every living lineage."""

    def __init__(self) -> None:
        self._poses: list[NDArray[np.float64]] = []   # per step: (rows, 3)
        self._parent: list[NDArray[np.intp]] = []     # per step: row of the step before, per row
        self._stamps: list[float] = []
        self._trunk = np.empty((0, 4))                 # rows t, x, y, theta shared by every lineage
        self._trunk_len = 0

    def __len__(self) -> int:
        return self._trunk_len + len(self._poses)

    @property
    def kept_rows(self) -> int:
        """Pose rows held: the trunk plus every living lineage's recent steps."""
        return self._trunk_len + sum(len(rows) for rows in self._poses)

    def append(self, stamp: float, poses: NDArray[np.float64], parent: NDArray[np.intp]) -> None:
        """One processed scan: poses (N, 3) after resampling; parent (N,) the slot of the
        previous scan each slot descends from."""
        self._poses.append(poses.copy())
        self._parent.append(parent)
        self._stamps.append(float(stamp))
        if len(self._poses) % PRUNE_EVERY == 0:
            self._prune()

    @property
    def latest(self) -> NDArray[np.float64] | None:
        """(N, 3) every slot's pose at the newest processed scan (None before the first);
        pruning never compacts the newest step, so its rows are the slots."""
        return self._poses[-1] if self._poses else None

    @property
    def settled(self) -> int:
        """Rows every lineage shares (the trunk): the first rows of every path, which no
        later update changes (a caller may keep what it made of them)."""
        return self._trunk_len

    def path(self, particle: int, start: int = 0) -> NDArray[np.float64]:
        """(T - start, 4) rows t, x, y, theta: the path of the particle in slot `particle`
        through every processed scan from the start-th on, following its ancestors back
        through resampling."""
        j = int(particle)
        t_len = len(self._poses)
        trunk = self._trunk_len
        out = np.empty((max(trunk + t_len - start, 0), 4))   # row k of the path is out[k - start]
        first = min(start, trunk)
        out[:trunk - first] = self._trunk[first:trunk]
        for t in range(t_len - 1, max(start - trunk, 0) - 1, -1):
            out[trunk + t - start, 0] = self._stamps[t]
            out[trunk + t - start, 1:] = self._poses[t][j]
            j = int(self._parent[t][j])
        return out

    def collapse(self, particle: int) -> None:
        """Every slot takes the path of slot `particle`: the history becomes one lineage,
        its rows but the newest in the trunk."""
        self._poses[-1][:] = self._poses[-1][particle]
        self._parent[-1][:] = self._parent[-1][particle]
        self._prune()

    def rewrite(self, first: int, poses: NDArray[np.float64]) -> None:
        """Rows first.. of the trunk take poses (K, 3) (after collapse: the one path)."""
        stop = first + len(poses)
        if first < 0 or stop > self._trunk_len:
            raise ValueError(f"rows {first}..{stop - 1} are not all in the trunk (its {self._trunk_len} rows)")
        self._trunk[first:stop, 1:] = poses

    def _prune(self) -> None:
        """Drops the steps no living particle descends from; moves the shared ones to the trunk."""
        keep = np.arange(len(self._poses[-1]))  # rows of step t that living particles descend from
        for t in range(len(self._poses) - 1, -1, -1):
            rows = np.unique(keep)
            new_row = np.full(len(self._poses[t]), -1, dtype=np.intp)
            new_row[rows] = np.arange(len(rows))
            if t + 1 < len(self._parent):
                self._parent[t + 1] = new_row[self._parent[t + 1]]
            if len(self._poses[t]) == 1:
                break  # a single lineage already: an earlier pruning compacted all before it
            keep = self._parent[t][rows]
            self._poses[t] = self._poses[t][rows]
            self._parent[t] = keep
        shared = next((t for t, rows in enumerate(self._poses) if len(rows) > 1), len(self._poses))
        shared = min(shared, len(self._poses) - 1)  # the newest step keeps its N slots
        if shared > 0:
            block = np.concatenate([np.array(self._stamps[:shared])[:, None],
                                    np.concatenate(self._poses[:shared])], axis=1)
            self._grow_trunk(block)
            del self._poses[:shared], self._parent[:shared], self._stamps[:shared]

    def _grow_trunk(self, block: NDArray[np.float64]) -> None:
        """Appends rows to the trunk, doubling its buffer when full (no copy per pruning)."""
        need = self._trunk_len + len(block)
        if need > len(self._trunk):
            grown = np.empty((max(need, 2 * len(self._trunk)), 4))
            grown[:self._trunk_len] = self._trunk[:self._trunk_len]
            self._trunk = grown
        self._trunk[self._trunk_len:need] = block
        self._trunk_len = need
