"""Plots of an estimate against its reference, with matplotlib's Agg canvas (no display,
no pyplot state): the two paths after alignment, and the position error over time."""
from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fastslam.eval.trajectory import align_2d, apply_alignment, match_by_time
from fastslam.io.staging import staged

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import ArrayLike


def plot_errors(path: str | os.PathLike[str], ref_t: ArrayLike, ref: ArrayLike, est_t: ArrayLike, est: ArrayLike,
                *, max_dt: float = 0.05, interpolate: bool = False, title: str = "") -> Path:
    """Write a PNG: left, the reference and the estimate aligned onto it (the ATE's rigid
    2D alignment) in the plane; right, each matched pose's position error over time, with
    the RMS as a line. Poses are matched as :func:`fastslam.eval.trajectory.score` does.

    Raises:
        ValueError: no estimate pose matches a reference pose.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    t, r, e = match_by_time(ref_t, ref, est_t, est, max_dt=max_dt, interpolate=interpolate)
    if len(t) == 0:
        raise ValueError("no estimate pose matches a reference pose in time")
    rot, shift = align_2d(e, r)
    aligned = apply_alignment(rot, shift, e)
    errors = np.hypot(*(aligned[:, :2] - r[:, :2]).T)
    rmse = float(np.sqrt(np.mean(errors ** 2)))
    ref_all = np.asarray(ref, dtype=np.float64).reshape(-1, 3)
    est_all = apply_alignment(rot, shift, est)

    fig = Figure(figsize=(11.0, 4.8), dpi=100)
    FigureCanvasAgg(fig)
    paths, error = fig.subplots(1, 2)
    paths.plot(ref_all[:, 0], ref_all[:, 1], color="tab:green", label="reference")
    paths.plot(est_all[:, 0], est_all[:, 1], color="tab:red", label="estimate (aligned)")
    paths.set_aspect("equal", adjustable="datalim")
    paths.set_xlabel("x [m]")
    paths.set_ylabel("y [m]")
    paths.legend(loc="best")
    paths.set_title("trajectories after alignment")
    error.plot(t - t[0], errors, color="tab:red", label="position error")
    error.axhline(rmse, color="black", linestyle="--", label=f"ATE (RMS) {rmse:.3f} m")
    error.set_xlabel(f"time since {t[0]:.2f} s [s]")
    error.set_ylabel("error after alignment [m]")
    error.set_ylim(bottom=0.0)
    error.legend(loc="best")
    error.set_title(f"position error over time ({len(t)} matched poses)")
    if title:
        fig.suptitle(title)
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.94 if title else 1.0))   # room for the title
    path = Path(path)
    with staged(path) as (tmp,):
        fig.savefig(str(tmp), format="png")
    return path
