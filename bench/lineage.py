"""Why the final path went where it did: the final best particle's ancestors, update by update.

    PYTHONPATH=src:. python -m bench.lineage BAG [--config FILE] [--seed S] [--set KEY=VALUE]...
                                             [--from T0] [--to T1] [--reference FILE]

Runs the bag as `python -m fastslam.offline` does, records every update (FastSlam.trace),
then follows the particle whose path the offline tool writes back through each resampling.
One row per update between T0 and T1 [s]: the ancestor's match (its score, whether it was
trusted, its correction of the noise-free motion prediction along, across and of the
heading), what the other trusted particles found (their number, median score and
correction), the ancestor's weight rank (1 = heaviest), what this scan added to its
log-weight against the update's best, Neff and whether the particles were resampled.
With a reference trajectory (the accuracy bench's `.gt.txt`, t x y theta or TUM), each
row also gives the final path's error there after aligning the whole path (as ATE does).

A wrong match trusted by one particle, outweighed by less than a nat, surviving dozens of
updates and then winning the resampling, reads as one row with a low score and a
correction unlike the others', then ranks near the bottom, then near the top.
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from fastslam.config import ConfigError, SlamConfig, parse_override
from fastslam.eval.trajectory import ate_errors, match_by_time
from fastslam.filter.slam import UpdateTrace
from fastslam.geometry import relative
from fastslam.io.bag_reader import BagError, read_bag
from fastslam.io.trajectory_files import TrajectoryError, read_trajectory
from fastslam.offline import DEFAULT_CONFIG, run_bag

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


def ancestors(parents: Sequence[NDArray[np.intp]], final: int) -> tuple[list[int], list[int]]:
    """(rows, slots): for each update, the row of the path arrays (after its resampling)
    and the slot of the per-update arrays (before it) of the ancestor of particle
    `final` of the last update. parents[k][i]: the slot before update k's resampling of
    the particle in slot i after it."""
    rows, slots = [0] * len(parents), [0] * len(parents)
    j = int(final)
    for k in range(len(parents) - 1, -1, -1):
        rows[k] = j
        j = int(parents[k][j])
        slots[k] = j
    return rows, slots


@dataclass(frozen=True)
class Row:
    """One update of the lineage (see the module's doc)."""

    t: float
    slot: int
    score: float          # nan: not matched
    trusted: bool
    correction: NDArray[np.float64] | None   # (3,) along, across [m], heading [rad]; None: no prediction
    others: int           # trusted matches of the other particles
    others_score: float   # their median score (nan: none)
    others_correction: NDArray[np.float64] | None
    rank: int             # 1 = heaviest before resampling
    log_w_step: float     # this scan's log-weight against the update's best (<= 0)
    n_eff: float
    resampled: bool
    pose: NDArray[np.float64]   # the path's pose (x, y, theta)


def lineage_rows(traces: Sequence[UpdateTrace], final: int) -> list[Row]:
    """The Row of each update for the ancestors of particle `final` of the last update."""
    rows, slots = ancestors([tr.parent for tr in traces], final)
    out = []
    for tr, row, s in zip(traces, rows, slots):
        m = tr.match
        score = float("nan") if m is None or m.score is None else float(m.score[s])
        trusted = bool(m is not None and m.trusted[s])
        rest = np.zeros(len(tr.weights), dtype=bool) if m is None else m.trusted.copy()
        rest[s] = False                                    # the other particles' trusted matches
        corr = others_corr = None
        if m is not None and tr.predicted is not None:
            c = relative(tr.predicted, m.poses)
            corr = c[s]
            others_corr = np.median(c[rest], axis=0) if rest.any() else None
        rest_n = int(np.count_nonzero(rest))
        others_score = float("nan")
        if m is not None and m.score is not None and rest_n:
            others_score = float(np.median(m.score[rest]))
        out.append(Row(t=tr.stamp, slot=s, score=score, trusted=trusted, correction=corr, others=rest_n,
                       others_score=others_score, others_correction=others_corr,
                       rank=1 + int(np.count_nonzero(tr.weights > tr.weights[s])),
                       log_w_step=float(tr.log_w_step[s]), n_eff=float(tr.n_eff), resampled=tr.resampled,
                       pose=np.asarray(tr.path[row], dtype=np.float64)))
    return out


def _corr(c: NDArray[np.float64] | None) -> str:
    return f"{'-':>21}" if c is None else f"{c[0]:+6.2f} {c[1]:+6.2f} {np.degrees(c[2]):+6.1f}"


def format_row(r: Row, error: float | None = None) -> str:
    line = (f"{r.t:9.2f} {r.slot:4d} {r.score:5.2f} {'yes' if r.trusted else 'no':>3} {_corr(r.correction)} | "
            f"{r.others:3d} {r.others_score:5.2f} {_corr(r.others_correction)} | "
            f"{r.rank:4d} {r.log_w_step:+6.2f} {r.n_eff:5.1f} {'yes' if r.resampled else 'no':>3}")
    return line if error is None else f"{line} {error:6.3f}"


HEADER = ("        t slot score tru  along across   turn |   n score  along across   turn | "
          "rank  dlogw  neff res")


def path_errors(rows: list[Row], reference: Path) -> NDArray[np.float64]:
    """(len(rows),) the error [m] of each row's pose against the reference, the whole path
    aligned to it first (nan where the reference has no pose within 0.01 s)."""
    ref_t, ref = read_trajectory(reference)
    t = np.array([r.t for r in rows])
    est = np.array([r.pose for r in rows]).reshape(-1, 3)
    tt, r, e = match_by_time(ref_t, ref, t, est, max_dt=0.01)
    if len(tt) < 2:
        raise TrajectoryError(f"{reference}: no pose within 0.01 s of the path's")
    err = ate_errors(r, e)        # aligns the whole path onto the reference first
    out = np.full(len(rows), np.nan)
    out[np.searchsorted(t, tt)] = err
    return out


def main(argv: list[str] | None = None) -> int:
    doc = __doc__ or ""
    parser = argparse.ArgumentParser(prog="python -m bench.lineage", description=doc.split("\n\n")[0])
    parser.add_argument("bag")
    parser.add_argument("--config", default=str(DEFAULT_CONFIG))
    parser.add_argument("--seed", type=int)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--from", dest="t0", type=float, default=-np.inf, metavar="T0")
    parser.add_argument("--to", dest="t1", type=float, default=np.inf, metavar="T1")
    parser.add_argument("--reference", type=Path, metavar="FILE")
    args = parser.parse_args(argv)
    traces: list[UpdateTrace] = []
    try:
        overrides = dict(parse_override(s) for s in args.set)
        if args.seed is not None:
            overrides["seed"] = args.seed
        cfg = SlamConfig.from_yaml(args.config, overrides)
        result = run_bag(read_bag(args.bag), cfg, trace=traces.append)
        life = traces[len(traces) - result.slam.updates:]    # after the filter's last reset
        if not life:
            raise BagError("no update was made")
        rows = lineage_rows(life, result.slam.best)
        errors = path_errors(rows, args.reference) if args.reference else None
    except (OSError, ConfigError, BagError, TrajectoryError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(HEADER + ("  error" if errors is not None else ""))
    for i, r in enumerate(rows):
        if args.t0 <= r.t <= args.t1:
            print(format_row(r, None if errors is None else float(errors[i])))
    return 0


if __name__ == "__main__":
    sys.exit(main())
