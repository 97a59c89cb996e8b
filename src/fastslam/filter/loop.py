"""A loop closed along the path (loop_spread).

When match_loop moves the particles onto a place seen long ago, each moved particle
jumps: its path ends with a step as long as the drift since it was last there (ACES
seed 1: 0.8 m at 867 s), and its map keeps the walls written during the drift, which
it meets again later (a corner mapped at 683 s, 0.58 m off at 1181 s). Here the jump
is spread back along the best particle's path since it was last at that place, as a
traverse is adjusted (each step turned by its share of the jump's turn, the rest spread
by distance travelled), and its map is written again from the scans kept, at the path's
new poses. A straight spread holds only for one loop: if the path came
back in between to a place seen before (it was anchored there already), or if no pose
of the path lies near the place found, the jump is left as it is.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fastslam.filter.scan import Beams
from fastslam.geometry import cos_sin, wrap_angle

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


class ScanStore:
    """The beams of every processed scan, kept to write the map again: ranges and the
    distance each clears as float32 (as a LaserScan carries them), the hits as bytes (9
    bytes a beam), the beam directions shared while the laser's do not change."""

    def __init__(self) -> None:
        self._ranges: list[NDArray[np.float32]] = []
        self._free: list[NDArray[np.float32]] = []
        self._hit: list[NDArray[np.bool_]] = []
        self._angles: list[NDArray[np.float64]] = []
        self._meta: list[tuple[float, tuple[float, float]]] = []

    def __len__(self) -> int:
        return len(self._ranges)

    def append(self, beams: Beams) -> None:
        same = bool(self._angles) and np.array_equal(self._angles[-1], beams.angles)
        angles = self._angles[-1] if same else beams.angles.copy()
        self._ranges.append(beams.ranges.astype(np.float32))
        self._free.append(beams.free_range.astype(np.float32))
        self._hit.append(beams.hit.copy())
        self._angles.append(angles)
        self._meta.append((beams.range_min, beams.mount))

    @property
    def nbytes(self) -> int:
        """Bytes held: 9 a beam, and each distinct set of beam directions once."""
        directions = {id(a): a.nbytes for a in self._angles}
        return 9 * sum(len(r) for r in self._ranges) + sum(directions.values())

    def beams(self, k: int) -> Beams:
        range_min, mount = self._meta[k]
        return Beams(angles=self._angles[k], ranges=self._ranges[k].astype(np.float64), hit=self._hit[k],
                     free_range=self._free[k].astype(np.float64), range_min=range_min, mount=mount)


def nearest_distances(points: NDArray[np.float64], others: NDArray[np.float64]) -> NDArray[np.float64]:
    """(P,) each point's (P, 2) distance to the nearest of others (Q, 2), a chunk of
    points at a time (a long run's path: no P x Q array, at most about 2**20 pairs)."""
    out = np.empty(len(points))
    chunk = max(1, 2 ** 20 // max(len(others), 1))
    for i in range(0, len(points), chunk):
        part = points[i:i + chunk]
        out[i:i + chunk] = np.hypot(part[:, None, 0] - others[None, :, 0], part[:, None, 1] - others[None, :, 1]).min(1)
    return out


def travelled(xy: NDArray[np.float64]) -> NDArray[np.float64]:
    """(T,) distance along the path (T, 2) from its first pose."""
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])


def loop_start(path: NDArray[np.float64], radius: float, recent: float) -> tuple[int | None, str]:
    """The row of path (T, 3) where the loop that ends at its last row began: the pose
    nearest the last one among those more than `recent` metres of travel before the
    jump (the jump is the last step: its length is not travel). None, and why, when
    that pose is farther than radius, or when the path between came within radius of
    a place seen before it (an inner loop: poses more than twice the radius of travel
    from the start on either side, and more than `recent` before the jump)."""
    d = travelled(path[:-1, :2])
    end = path[-1, :2]
    before = np.flatnonzero(d < d[-1] - recent)
    if len(before) == 0:
        return None, f"no pose {recent:g} m of travel before"
    gap = np.hypot(*(path[before, :2] - end).T)
    start = int(before[np.argmin(gap)])
    if gap.min() > radius:
        return None, f"the path's nearest pose lies {gap.min():.2f} m from the place found"
    # the path near the start is the start's own place: a pose twice the radius of travel away that
    # comes back within the radius has come back (the end's approach: `recent`, as above)
    older = np.flatnonzero(d < d[start] - 2 * radius)
    between = np.flatnonzero((d > d[start] + 2 * radius) & (d < d[-1] - recent))
    if len(older) and len(between):
        near = float(nearest_distances(path[between, :2], path[older, :2]).min())
        if near < radius:
            return None, f"the path came back to a place seen before the loop's start ({near:.2f} m)"
    return start, ""


def spread_jump(path: NDArray[np.float64], start: int, before: NDArray[np.float64],
                after: NDArray[np.float64]) -> NDArray[np.float64]:
    """path (T, 3) with the jump before -> after (3,) (the last pose, moved from
    `before` to `after`) spread over rows start..T-2, as a traverse is adjusted: each
    step turned by its share of the jump's turn (the share of the travel from row start
    done at its middle), then each pose moved by its share of what is left, so that row
    T-2 lands where the jump takes it (its pose relative to `before` kept relative to
    `after`). Row start, the rows before it and the last row stay."""
    out = path.copy()
    if len(path) - 2 <= start:
        return out
    seg = path[start:-1]
    d = travelled(seg[:, :2])
    share = d / d[-1] if d[-1] > 0 else np.linspace(0.0, 1.0, len(d))
    turn = float(wrap_angle(after[2] - before[2]))
    # unlike filter/smooth.py's gaps (one correction, scaled by each pose's share), each step is turned:
    # a turn spread as one rigid correction swings the far end of a long loop (edmonton seed 4)
    c, s = cos_sin(0.5 * (share[:-1] + share[1:]) * turn)
    steps = np.diff(seg[:, :2], axis=0)
    turned = np.stack([c * steps[:, 0] - s * steps[:, 1], s * steps[:, 0] + c * steps[:, 1]], axis=1)
    xy = seg[0, :2] + np.concatenate([np.zeros((1, 2)), np.cumsum(turned, axis=0)])
    # where the jump takes row T-2: after composed with its pose relative to before
    ct, st = cos_sin(turn)
    v = seg[-1, :2] - before[:2]
    target = after[:2] + np.array([ct * v[0] - st * v[1], st * v[0] + ct * v[1]])
    xy += share[:, None] * (target - xy[-1])
    out[start + 1:-1, :2] = xy[1:]
    out[start + 1:-1, 2] = wrap_angle(seg[1:, 2] + share[1:] * turn)
    return out
