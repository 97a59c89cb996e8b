"""Plain-text 2D trajectories: one ``t x y theta`` line per pose, ``#`` starts a comment;
or TUM's ``t x y z qx qy qz qw`` (what `evo` reads), z = 0 and a rotation about z.
Relations files (Kuemmerle et al. 2009): ``t1 t2 x y z roll pitch yaw`` per line."""
from __future__ import annotations

import math
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fastslam.geometry import yaw_from_quaternion

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import ArrayLike, NDArray


class TrajectoryError(ValueError):
    """A trajectory file that cannot be read."""


FORMATS = ("xytheta", "tum")


def write_trajectory(path: str | os.PathLike[str], times: ArrayLike, poses: ArrayLike, *,
                     comment: str = "", fmt: str = "xytheta") -> Path:
    """Write (T,) times [s] and (T, 3) poses (x, y, theta) [m, m, rad], full precision,
    as ``t x y theta`` (fmt "xytheta") or ``t x y z qx qy qz qw`` (fmt "tum")."""
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    if len(t) != len(p):
        raise ValueError(f"{len(t)} times but {len(p)} poses")
    if fmt not in FORMATS:
        raise ValueError(f"unknown trajectory format {fmt!r} (one of {', '.join(FORMATS)})")
    lines = [f"# {line}" for line in comment.splitlines()]
    # repr-precision floats: a written trajectory reads back bit-for-bit (t x y theta)
    if fmt == "tum":
        qz, qw = np.sin(p[:, 2] / 2), np.cos(p[:, 2] / 2)
        lines += ["# t x y z qx qy qz qw"]
        lines += [f"{ti!r} {x!r} {y!r} 0.0 0.0 0.0 {z!r} {w!r}"
                  for ti, (x, y, _), z, w in zip(t.tolist(), p.tolist(), qz.tolist(), qw.tolist())]
    else:
        lines += ["# t x y theta"]
        lines += [f"{ti!r} {x!r} {y!r} {th!r}" for ti, (x, y, th) in zip(t.tolist(), p.tolist())]
    path = Path(path)
    path.write_text("\n".join(lines) + "\n")
    return path


def _text(path: str | os.PathLike[str], what: str) -> str:
    """The file's text; TrajectoryError for a missing or binary file."""
    try:
        return Path(path).read_text(encoding="utf-8")
    except OSError as err:
        raise TrajectoryError(f"cannot read {what} {path}: {err.strerror}") from err
    except UnicodeDecodeError:
        raise TrajectoryError(f"{path} is not a text file of {what} lines") from None


def read_trajectory(path: str | os.PathLike[str]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """-> ((T,) times sorted ascending, (T, 3) poses). A line of 8 numbers is TUM's
    ``t x y z qx qy qz qw`` (the heading from the quaternion); otherwise columns after
    the fourth are ignored.

    Raises:
        TrajectoryError: missing file, or a line with fewer than 4 numbers.
    """
    rows: list[list[float]] = []
    text = _text(path, "trajectory")
    for number, line in enumerate(text.splitlines(), start=1):
        body = line.split("#", 1)[0].replace(",", " ").split()
        if not body:
            continue
        try:
            values = [float(v) for v in body[:8]]
        except ValueError:
            raise TrajectoryError(f"{path}:{number}: not numbers: {line.strip()[:80]!r}") from None
        if not all(math.isfinite(v) for v in values):
            raise TrajectoryError(f"{path}:{number}: NaN or infinite values: {line.strip()[:80]!r}")
        if len(body) < 4:
            raise TrajectoryError(f"{path}:{number}: expected 't x y theta', got {line.strip()!r}")
        if len(body) == 8:
            values[3] = yaw_from_quaternion(*values[4:8])
        rows.append(values[:4])
    data = np.asarray(rows, dtype=np.float64).reshape(-1, 4)
    order = np.argsort(data[:, 0], kind="stable")
    return data[order, 0], data[order, 1:]


def read_relations(path: str | os.PathLike[str]) -> NDArray[np.float64]:
    """(R, 5) rows t1, t2, x, y, yaw of a relations file (``t1 t2 x y z roll pitch yaw``:
    the true motion from the pose at t1 to the pose at t2, in the frame of the first).

    Raises:
        TrajectoryError: missing file, a line that is not 8 numbers, or no relation.
    """
    text = _text(path, "relations")
    rows: list[list[float]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        body = line.split("#", 1)[0].split()
        if not body:
            continue
        try:
            values = [float(v) for v in body]
        except ValueError:
            raise TrajectoryError(f"{path}:{number}: not numbers: {line.strip()!r}") from None
        if len(values) != 8 or not all(np.isfinite(values)):
            raise TrajectoryError(f"{path}:{number}: expected 't1 t2 x y z roll pitch yaw', got {line.strip()!r}")
        rows.append([values[0], values[1], values[2], values[3], values[7]])
    if not rows:
        raise TrajectoryError(f"{path}: no relations")
    return np.asarray(rows, dtype=np.float64)
