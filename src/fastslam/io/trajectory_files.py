"""Plain-text 2D trajectories: one ``t x y theta`` line per pose, ``#`` starts a comment."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray


class TrajectoryError(ValueError):
    """A trajectory file that cannot be read."""


def write_trajectory(path: str | os.PathLike[str], times: ArrayLike, poses: ArrayLike, *,
                     comment: str = "") -> Path:
    """Write (T,) times [s] and (T, 3) poses (x, y, theta) [m, m, rad], full precision."""
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    if len(t) != len(p):
        raise ValueError(f"{len(t)} times but {len(p)} poses")
    lines = [f"# {line}" for line in comment.splitlines()] + ["# t x y theta"]
    # repr-precision floats: a written trajectory reads back bit-for-bit
    lines += [f"{ti!r} {x!r} {y!r} {th!r}" for ti, (x, y, th) in zip(t.tolist(), p.tolist())]
    path = Path(path)
    path.write_text("\n".join(lines) + "\n")
    return path


def read_trajectory(path: str | os.PathLike[str]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """-> ((T,) times sorted ascending, (T, 3) poses). Extra columns are ignored.

    Raises:
        TrajectoryError: missing file, or a line with fewer than 4 numbers.
    """
    rows: list[list[float]] = []
    try:
        text = Path(path).read_text()
    except OSError as err:
        raise TrajectoryError(f"cannot read trajectory {path}: {err.strerror}") from err
    for number, line in enumerate(text.splitlines(), start=1):
        body = line.split("#", 1)[0].replace(",", " ").split()
        if not body:
            continue
        try:
            rows.append([float(v) for v in body[:4]])
        except ValueError:
            raise TrajectoryError(f"{path}:{number}: not numbers: {line.strip()!r}") from None
        if len(body) < 4:
            raise TrajectoryError(f"{path}:{number}: expected 't x y theta', got {line.strip()!r}")
    data = np.asarray(rows, dtype=np.float64).reshape(-1, 4)
    order = np.argsort(data[:, 0], kind="stable")
    return data[order, 0], data[order, 1:]
