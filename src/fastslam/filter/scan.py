"""A laser scan as the core sees it, and the beams an update uses."""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from fastslam.config import SlamConfig
from fastslam.geometry import wrap_angle

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import ArrayLike, NDArray


@dataclass(frozen=True)
class Scan:
    """One sweep, already in the robot's base frame.

    ranges: (M,) measured ranges [m]; NaN, inf or >= range_max mean no return.
    angles: (M,) beam directions in the base frame [rad] (the laser's mounting yaw and
        any upside-down mounting already applied).
    mount: (x, y) of the laser origin in the base frame [m].
    stamp: time of the sweep [s].
    """

    ranges: NDArray[np.float64]
    angles: NDArray[np.float64]
    range_min: float
    range_max: float
    mount: tuple[float, float] = (0.0, 0.0)
    stamp: float = 0.0

    @classmethod
    def from_laser(cls, ranges: ArrayLike, angle_min: float, angle_increment: float,
                   range_min: float, range_max: float, *, mount: tuple[float, float, float] = (0.0, 0.0, 0.0),
                   upside_down: bool = False, stamp: float = 0.0) -> Scan:
        """From LaserScan fields; mount = (x, y, yaw) of the laser in the base frame.

        An upside-down laser sweeps the other way round as seen from above.
        """
        r = np.asarray(ranges, dtype=np.float64)
        return cls(ranges=r, angles=_beam_angles(angle_min, angle_increment, len(r), upside_down, mount[2]),
                   range_min=float(range_min), range_max=float(range_max),
                   mount=(float(mount[0]), float(mount[1])), stamp=float(stamp))


@functools.lru_cache(maxsize=16)
def _beam_angles(angle_min: float, angle_increment: float, count: int, upside_down: bool,
                 yaw: float) -> NDArray[np.float64]:
    """(count,) base-frame beam directions of Scan.from_laser, read only: the same every scan."""
    a = angle_min + angle_increment * np.arange(count)
    a = -a if upside_down else a
    out = wrap_angle(a + yaw)
    out.flags.writeable = False
    return out


@dataclass(frozen=True)
class Beams:
    """The beams of one scan an update uses, classified.

    angles: (B,) base-frame directions; ranges: (B,) measured ranges.
    hit: (B,) a return inside max_range (or mark_range): weighs the particle and marks its end cell.
    free_range: (B,) the distance each beam clears (0: it clears nothing) [m]; a hit
        farther than it (past max_range, short of mark_range) marks its end cell only.
    """

    angles: NDArray[np.float64]
    ranges: NDArray[np.float64]
    hit: NDArray[np.bool_]
    free_range: NDArray[np.float64]
    range_min: float
    mount: tuple[float, float] = field(default=(0.0, 0.0))


def laser_problem(count: int, angle_min: float, angle_increment: float, range_min: float,
                  range_max: float, angle_max: float | None = None) -> str | None:
    """Why a scan's geometry is unusable, or None. Readings themselves are classified
    later (select_beams); this only rejects what cannot be interpreted at all."""
    if count == 0:
        return "empty scan"
    for name, v in (("angle_min", angle_min), ("angle_increment", angle_increment),
                    ("range_min", range_min), ("range_max", range_max)):
        if not math.isfinite(v):
            return f"scan {name} is {v}"
    if angle_increment == 0:
        return "scan angle_increment is 0"
    if range_max <= 0 or range_max <= range_min:
        return f"scan range_max={range_max} must exceed range_min={range_min} and 0"
    if angle_max is not None and math.isfinite(angle_max):
        implied = (angle_max - angle_min) / angle_increment + 1
        # One beam either way is common (0..2pi lidars count the fence post differently).
        if abs(implied - count) > 1.5:
            return f"scan has {count} ranges but its angles imply {implied:.0f}"
    return None


def in_fov(angles: NDArray[np.float64], cfg: SlamConfig, beam_step: int = 1) -> NDArray[np.bool_]:
    """(M,) which beams (base-frame directions) lie in the field of view fov_min..fov_max
    (and, beam_step > 1, are every beam_step-th beam), read only."""
    a = np.ascontiguousarray(angles, dtype=np.float64)
    return _in_fov(a.tobytes(), cfg.fov_min, cfg.fov_max, beam_step)


@functools.lru_cache(maxsize=16)
def _in_fov(angles: bytes, fov_min: float, fov_max: float, beam_step: int) -> NDArray[np.bool_]:
    """in_fov of the float64 angles in these bytes: a laser's angles are the same every scan."""
    deg = np.degrees(wrap_angle(np.frombuffer(angles, dtype=np.float64)))
    keep = (deg >= fov_min) & (deg <= fov_max)
    if beam_step > 1:
        keep &= (np.arange(len(keep)) % beam_step) == 0
    keep.flags.writeable = False
    return keep


def fov_problem(scan: Scan, cfg: SlamConfig) -> str | None:
    """Why no beam of the scan can be used (none in the field of view), or None."""
    if in_fov(scan.angles, cfg).any():
        return None
    first, last = np.degrees(wrap_angle(scan.angles[[0, -1]]))
    return (f"no beam in the field of view fov_min..fov_max = {cfg.fov_min:g}..{cfg.fov_max:g} deg "
            f"(the scan sweeps from {first:.0f} to {last:.0f} deg in the base frame)")


def select_beams(scan: Scan, cfg: SlamConfig) -> Beams:
    """Field of view, every k-th beam, and the class of each reading.

    Readings below range_min (zero, negative) are ignored; NaN, inf and >= range_max
    are no-returns that clear free space up to no_return_range; returns beyond the
    filter's max_range clear up to max_range and mark nothing, unless short of
    mark_range: then they are hits that clear up to max_range only.
    """
    keep = in_fov(scan.angles, cfg, cfg.beam_step)
    z = scan.ranges[keep]
    with np.errstate(invalid="ignore"):
        no_return = ~np.isfinite(z) | (z >= scan.range_max)
        short = ~no_return & (z < scan.range_min)
    ok = ~no_return & ~short
    hit = ok & (z < max(cfg.max_range, cfg.mark_range))
    free = np.zeros(len(z))
    free[hit] = np.minimum(z[hit], cfg.max_range)
    free[ok & ~hit] = cfg.max_range
    free[no_return] = min(cfg.no_return_range, cfg.max_range)
    return Beams(angles=scan.angles[keep], ranges=np.where(ok, z, np.inf), hit=hit,
                 free_range=free, range_min=scan.range_min, mount=scan.mount)


def spread_returns(beams: Beams, count: int) -> NDArray[np.intp]:
    """Indices of at most count returns (beams.hit), evenly spread over the scan."""
    sel = np.flatnonzero(beams.hit)
    if len(sel) <= count:
        return sel
    return sel[_spread(len(sel), count)]


@functools.lru_cache(maxsize=256)
def _spread(n: int, count: int) -> NDArray[np.intp]:
    """Which count of n items, evenly spread (read only): the same few (n, count) every scan."""
    at = np.unique(np.linspace(0, n - 1, count).astype(np.intp))
    at.flags.writeable = False
    return at


def returns_subset(beams: Beams, count: int) -> Beams:
    """The beams of at most count returns, evenly spread: the end points the matcher
    uses, and the likelihood weight with them (an end point costs a 2-D search)."""
    sel = spread_returns(beams, count)
    return Beams(angles=beams.angles[sel], ranges=beams.ranges[sel], hit=beams.hit[sel],
                 free_range=beams.free_range[sel], range_min=beams.range_min, mount=beams.mount)


def end_points(beams: Beams, sel: NDArray[np.intp]) -> NDArray[np.float64]:
    """(M, 2) end points of the selected beams in the robot frame [m]."""
    r = beams.ranges[sel]
    a = beams.angles[sel]
    return np.stack([beams.mount[0] + r * np.cos(a), beams.mount[1] + r * np.sin(a)], axis=1)
