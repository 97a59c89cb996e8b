"""CARMEN log reader (plain text or gzip): FLASER, ROBOTLASER1 and ODOM lines.

Line formats (CARMEN logger; timestamps in seconds):

- ``FLASER n r1..rn x y theta odom_x odom_y odom_theta ipc_timestamp host logger_timestamp``
  ``x y theta`` is the laser's pose, ``odom_*`` the robot's odometry pose. FLASER has
  no angle fields: the beams cover 180 degrees from -90 degrees, 1 degree apart for
  180 or 181 readings (0.5 degrees for 360/361), i.e. ``angle_min = -pi/2`` and
  ``angle_increment = pi / (n - n % 2)``; with 180 readings the last beam is at +89
  degrees, as gmapping's CARMEN reader does. Readings ``>= max_range`` (81.83 m,
  the SICK "no return" value, or where the readings show the laser saturating lower:
  ``saturation_range``) mean no return and become ``inf``.
- ``ROBOTLASER1 laser_type start_angle fov angular_res max_range accuracy remission_mode
  n r1..rn m rem1..remm laser_x laser_y laser_theta robot_x robot_y robot_theta
  tv rv forward_safety_dist side_safety_dist turn_axis ipc_timestamp host logger_timestamp``
- ``ODOM x y theta tv rv accel ipc_timestamp host logger_timestamp``
- ``PARAM robot_frontlaser_offset <m>`` gives the FLASER laser's forward offset.

Everything else (NEFF, TRUEPOS, SYNC, comments, ...) is skipped.
"""
from __future__ import annotations

import dataclasses
import gzip
import math
import os
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, TYPE_CHECKING, Iterator

import numpy as np

from fastslam.geometry import relative

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


FLASER_MAX_RANGE = 81.83  # [m] SICK LMS "no return" reading in CARMEN logs


class CarmenError(ValueError):
    """A malformed line in a CARMEN log (the message names the line number)."""


@dataclass(frozen=True)
class LaserRecord:
    """One laser scan.

    Attributes:
        t: logger timestamp [s]; ipc_t: the sender's timestamp [s].
        ranges: (M,) float32 [m], ``inf`` where there was no return.
        angle_min, angle_increment: beam i points at angle_min + i * angle_increment [rad], laser frame.
        max_range: readings at or beyond this were no returns [m].
        laser_pose, robot_pose: (3,) float64 (x, y, theta) in the log's world frame.
        remissions: (K,) float32, empty for FLASER.
        kind: "FLASER" or "ROBOTLASER1".
    """

    t: float
    ipc_t: float
    ranges: NDArray[np.float32]
    angle_min: float
    angle_increment: float
    max_range: float
    laser_pose: NDArray[np.float64]
    robot_pose: NDArray[np.float64]
    kind: str
    remissions: NDArray[np.float32] = field(default_factory=lambda: np.zeros(0, np.float32))

    @property
    def mount(self) -> tuple[float, float, float]:
        """The laser's pose (x, y, yaw) on the robot, from the record's two poses."""
        m = relative(self.robot_pose, self.laser_pose)
        return float(m[0]), float(m[1]), float(m[2])


@dataclass(frozen=True)
class OdomLine:
    """An ODOM line: pose (3,) (x, y, theta), velocities tv [m/s], rv [rad/s]."""

    t: float
    ipc_t: float
    pose: NDArray[np.float64]
    tv: float
    rv: float


@dataclass
class CarmenLog:
    """Parsed log: scans and odometry in file order, plus the PARAM lines as strings."""

    scans: list[LaserRecord]
    odometry: list[OdomLine]
    params: dict[str, str]
    skipped: list[str] = field(default_factory=list)  # ODOM lines left out, each with its line and why
    saturation: float | None = None  # [m] FLASER readings from here on taken as no returns (saturation_range)

    @property
    def front_laser_offset(self) -> float:
        """Forward offset of the FLASER laser from the robot centre [m] (0 if not logged)."""
        return float(self.params.get("robot_frontlaser_offset", 0.0))

    def laser_mount(self) -> tuple[float, float, float]:
        """Laser pose on the robot (x, y, yaw): from ROBOTLASER1's two poses, else the
        FLASER front-laser offset PARAM (0 when not logged)."""
        for s in self.scans:
            if s.kind == "ROBOTLASER1":
                return s.mount
        return self.front_laser_offset, 0.0, 0.0


def open_log(path: str | os.PathLike[str]) -> IO[str]:
    """The log's text (gzip detected by content), for iter_log: a log read line by line."""
    return _open_text(Path(path))


def _open_text(path: Path) -> IO[str]:
    with path.open("rb") as f:
        gz = f.read(2) == b"\x1f\x8b"  # gzip magic, whatever the file is called
    if gz:
        return gzip.open(path, "rt", encoding="ascii", errors="replace")
    return path.open("r", encoding="ascii", errors="replace")


def flaser_geometry(n: int) -> tuple[float, float]:
    """(angle_min, angle_increment) of an n-beam FLASER scan spanning 180 degrees."""
    return -math.pi / 2, math.pi / max(1, n - n % 2)


MAX_STAMP = 2.0**32  # [s] ROS 1 time holds seconds in 32 bits


class BadStamp(ValueError):
    """A timestamp no ROS 1 time can hold."""


def _stamp(value: str) -> float:
    """A timestamp field [s]: finite, not negative, one ROS 1 time can hold."""
    t = float(value)
    if not 0.0 <= t < MAX_STAMP:
        raise BadStamp(f"timestamp {value} is not in [0, 2^32) s")
    return t


def _pose(values: list[str]) -> NDArray[np.float64]:
    p = np.asarray(values, dtype=np.float64)
    if not np.all(np.isfinite(p)):
        raise ValueError(f"pose {' '.join(values)} is not finite")
    return p


def _no_return(values: list[str], max_range: float) -> NDArray[np.float32]:
    r = np.asarray(values, dtype=np.float64)
    # compare in float64 before the cast: 81.83 in float32 is not 81.83
    return np.where(r >= max_range - 1e-6, np.inf, r).astype(np.float32)


def parse_flaser(tok: list[str], *, max_range: float = FLASER_MAX_RANGE) -> LaserRecord:
    """Tokens of one FLASER line (tok[0] == 'FLASER') -> LaserRecord."""
    n = int(tok[1])
    if len(tok) < n + 11:
        raise ValueError(f"FLASER with {n} readings needs {n + 11} fields, got {len(tok)}")
    rest = tok[2 + n:]
    angle_min, inc = flaser_geometry(n)
    return LaserRecord(
        t=_stamp(rest[8]), ipc_t=float(rest[6]),
        ranges=_no_return(tok[2:2 + n], max_range),
        angle_min=angle_min, angle_increment=inc, max_range=max_range,
        laser_pose=_pose(rest[0:3]), robot_pose=_pose(rest[3:6]), kind="FLASER")


def parse_robotlaser1(tok: list[str], *, max_range: float | None = None) -> LaserRecord:
    """Tokens of one ROBOTLASER1 line -> LaserRecord; ``max_range`` overrides the logged one."""
    start, _fov, res, logged_max = (float(v) for v in tok[2:6])
    n = int(tok[8])
    k = int(tok[9 + n])
    rest = tok[10 + n + k:]
    if len(rest) < 14:
        raise ValueError(f"ROBOTLASER1 with {n} readings and {k} remissions is too short")
    limit = logged_max if max_range is None else max_range
    return LaserRecord(
        t=_stamp(rest[13]), ipc_t=float(rest[11]),
        ranges=_no_return(tok[9:9 + n], limit),
        angle_min=start, angle_increment=res, max_range=limit,
        laser_pose=_pose(rest[0:3]), robot_pose=_pose(rest[3:6]), kind="ROBOTLASER1",
        remissions=np.asarray(tok[10 + n:10 + n + k], dtype=np.float32))


def parse_odom(tok: list[str]) -> OdomLine:
    """Tokens of one ODOM line -> OdomLine."""
    return OdomLine(t=_stamp(tok[9]), ipc_t=float(tok[7]), pose=_pose(tok[1:4]),
                    tv=float(tok[4]), rv=float(tok[5]))


def iter_log(lines: Iterator[str] | IO[str], *, max_range: float | None = None
             ) -> Iterator[LaserRecord | OdomLine | tuple[str, str]]:
    """Parse lines lazily; yields LaserRecord, OdomLine, ("PARAM", "name value") or
    ("SKIPPED", why) for an ODOM line with a timestamp no ROS time holds.

    Raises:
        CarmenError: a known message type with missing or non-numeric fields.
    """
    number = 0
    try:
        for number, line in enumerate(lines, start=1):
            tok = line.split()
            if not tok:
                continue
            try:
                if tok[0] == "FLASER":
                    yield parse_flaser(tok, max_range=FLASER_MAX_RANGE if max_range is None else max_range)
                elif tok[0] == "ROBOTLASER1":
                    yield parse_robotlaser1(tok, max_range=max_range)
                elif tok[0] == "ODOM":
                    try:
                        yield parse_odom(tok)
                    except BadStamp as err:  # the converter does not need ODOM lines (seattle has one)
                        yield ("SKIPPED", f"line {number}: ODOM {err}")
                elif tok[0] == "PARAM" and len(tok) >= 3:
                    yield ("PARAM", f"{tok[1]} {tok[2]}")
            except (ValueError, IndexError) as err:
                raise CarmenError(f"line {number}: bad {tok[0]} message: {err}") from None
    except (EOFError, OSError, zlib.error) as err:  # reading the next line failed
        raise CarmenError(f"line {number + 1}: the file ends early or is corrupt (truncated gzip?): {err}") from None


# A laser that finds nothing within its range reports its largest reading: FLASER logs
# carry no maximum, and besides the SICK's 81.83 m some logs saturate lower (the Orebro
# log at 32.76 m, the largest millimetre count an int16 holds; Edmonton and Acapulco at
# 51.1 m). Thousands of readings in one band of a few centimetres at the top of the
# distribution are that value, not a wall: a wall's readings spread with the robot's
# positions. Taken as returns, they drew walls 32 m away in every open direction.
SATURATION_BIN = 0.1        # [m] width of the band
SATURATION_SHARE = 0.005    # the band holds at least this share of all readings ...
SATURATION_ABOVE = 0.0005   # ... and at most this share lies beyond it


def saturation_range(scans: list[LaserRecord]) -> float | None:
    """The reading [m] from which the scans' readings are the laser's no-return value:
    the lower edge, less one band, of the lowest SATURATION_BIN band that holds at least
    SATURATION_SHARE of the finite readings with at most SATURATION_ABOVE of them beyond
    it; None when the readings show no such band (or are fewer than 1000)."""
    r = np.concatenate([s.ranges for s in scans]) if scans else np.zeros(0, np.float32)
    r = r[np.isfinite(r)]
    if len(r) < 1000:
        return None
    counts = np.bincount((r / SATURATION_BIN).astype(np.intp))
    beyond = np.cumsum(counts[::-1])[::-1] - counts       # readings in the bands above each band
    band = np.flatnonzero((counts >= SATURATION_SHARE * len(r)) & (beyond <= SATURATION_ABOVE * len(r)))
    return None if len(band) == 0 else float((band[0] - 1) * SATURATION_BIN)


def read_log(path: str | os.PathLike[str], *, max_range: float | None = None,
             limit: int | None = None) -> CarmenLog:
    """Read a CARMEN log (gzip detected by content).

    Args:
        path: the log file.
        max_range: no-return threshold [m]; default 81.83 for FLASER (or lower where the
            readings show the laser saturating, saturation_range), the logged value for ROBOTLASER1.
        limit: stop after this many laser scans (for quick tests).
    """
    scans: list[LaserRecord] = []
    odometry: list[OdomLine] = []
    params: dict[str, str] = {}
    skipped: list[str] = []
    with _open_text(Path(path)) as f:
        for item in iter_log(f, max_range=max_range):
            if isinstance(item, LaserRecord):
                scans.append(item)
                if limit is not None and len(scans) >= limit:
                    break
            elif isinstance(item, OdomLine):
                odometry.append(item)
            elif item[0] == "SKIPPED":
                skipped.append(item[1])
            else:
                name, value = item[1].split(" ", 1)
                params[name] = value
    saturation = None
    if max_range is None:
        saturation = saturation_range([sc for sc in scans if sc.kind == "FLASER"])
        if saturation is not None and saturation < FLASER_MAX_RANGE:
            scans = [dataclasses.replace(sc, max_range=saturation,
                                         ranges=np.where(sc.ranges >= saturation, np.inf, sc.ranges).astype(np.float32))
                     if sc.kind == "FLASER" else sc for sc in scans]
        else:
            saturation = None
    return CarmenLog(scans=scans, odometry=odometry, params=params, skipped=skipped, saturation=saturation)
