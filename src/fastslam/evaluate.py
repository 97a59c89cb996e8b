"""Score an estimated 2D trajectory against a reference (ATE and RPE), or against
ground-truth relations (the Kuemmerle et al. 2009 metric).

    python -m fastslam.evaluate REFERENCE ESTIMATE [--max-dt 0.05] [--interpolate] [--delta 1] [--json]
                                [--plot FILE.png]
    python -m fastslam.evaluate --relations FILE ESTIMATE [--worst N] [--json]

Trajectory files hold ``t x y theta`` lines or TUM's ``t x y z qx qy qz qw`` (``#``
comments allowed), e.g. ``out.bag.gt.txt`` from ``python -m fastslam.carmen_to_bag`` and a
SLAM run's trajectory; a relations file ``t1 t2 x y z roll pitch yaw`` lines. See
:mod:`fastslam.eval.trajectory` for the definitions. ``--plot`` draws both trajectories
after the alignment and the position error over time (matplotlib); ``--worst N`` lists
the N relations the estimate errs most on (where a run went wrong).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fastslam.cli import closed_output_ends_quietly
from fastslam.eval.trajectory import RelationScores, TrajectoryScores, relations_score, score, worst_relations
from fastslam.io.trajectory_files import TrajectoryError, read_relations, read_trajectory

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    import numpy as np
    from numpy.typing import NDArray


def format_table(s: TrajectoryScores) -> str:
    """Human-readable summary, one metric per line."""
    rows = [("matched poses", f"{s.matched}"),
            ("ATE rmse [m]", f"{s.ate_rmse:.4f}"), ("ATE mean [m]", f"{s.ate_mean:.4f}"),
            ("ATE max [m]", f"{s.ate_max:.4f}"),
            (f"RPE trans rmse [m / {s.rpe_delta} pose]", f"{s.rpe_trans:.4f}"),
            (f"RPE rot rmse [deg / {s.rpe_delta} pose]", f"{s.rpe_rot:.4f}")]
    width = max(len(k) for k, _ in rows)
    return "\n".join(f"{k:<{width}}  {v:>10}" for k, v in rows)


def format_relations(s: RelationScores) -> str:
    """Human-readable relations metric: mean +- std (max) per error."""
    rows = [("relations", f"{s.relations} ({s.outside} outside the estimate's time span, clamped)"),
            ("translation [m]", f"{s.trans_mean:.4f} +- {s.trans_std:.4f} (max {s.trans_max:.4f})"),
            ("rotation [deg]", f"{s.rot_mean:.4f} +- {s.rot_std:.4f} (max {s.rot_max:.4f})")]
    return "\n".join(f"{k:<16} {v}" for k, v in rows)


WORST_KEYS = ("t1", "t2", "length", "trans", "rot", "speed")


def format_worst(rows: NDArray[np.float64]) -> str:
    """The worst relations (worst_relations' rows), one a line."""
    head = f"{'t1 [s]':>14} {'t2 [s]':>14} {'length [m]':>10} {'error [m]':>9} {'[deg]':>7} {'speed [m/s]':>11}"
    return "\n".join([f"worst {len(rows)}:", head] + [
        f"{t1:14.3f} {t2:14.3f} {length:10.3f} {trans:9.3f} {rot:7.2f} {speed:11.2f}"
        for t1, t2, length, trans, rot, speed in rows])


@closed_output_ends_quietly
def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m fastslam.evaluate", description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="+", metavar="REFERENCE ESTIMATE",
                    help="reference and estimated trajectories; with --relations the estimate only")
    ap.add_argument("--relations", metavar="FILE", help="score the estimate against these relations instead")
    ap.add_argument("--max-dt", type=float, default=0.05, help="nearest-time matching tolerance [s]")
    ap.add_argument("--interpolate", action="store_true", help="interpolate the reference instead")
    ap.add_argument("--delta", type=int, default=1, help="RPE over matched poses this many apart")
    ap.add_argument("--json", action="store_true", help="print the scores as JSON")
    ap.add_argument("--plot", metavar="FILE.png", help="also draw the aligned trajectories and the error over time")
    ap.add_argument("--worst", type=int, metavar="N", default=0,
                    help="with --relations: also list the N relations with the largest translation errors")
    args = ap.parse_args(argv)
    wanted = 1 if args.relations else 2
    if len(args.files) != wanted:
        ap.error("--relations FILE takes one ESTIMATE" if args.relations else "expected REFERENCE ESTIMATE")
    if args.relations and args.plot:
        ap.error("--plot draws an estimate against a reference trajectory, not against relations")
    if args.worst and not args.relations:
        ap.error("--worst lists relations: it needs --relations FILE")
    if args.worst < 0:
        ap.error(f"--worst must be at least 0 (got {args.worst})")
    if args.delta < 1 or not args.max_dt >= 0:
        print(f"error: --delta must be at least 1 (got {args.delta}) and --max-dt at least 0 (got {args.max_dt})",
              file=sys.stderr)
        return 2
    try:
        if args.relations:
            relations = read_relations(args.relations)
            est_t, est = read_trajectory(args.files[0])
            if len(est_t) == 0:
                raise TrajectoryError(f"{args.files[0]}: no poses")
            r = relations_score(est_t, est, relations)
            scores: dict[str, Any] = dict(r.as_dict())
            table = format_relations(r)
            if args.worst:
                worst = worst_relations(est_t, est, relations, args.worst)
                scores["worst"] = [{k: (None if math.isinf(v) else float(v)) for k, v in zip(WORST_KEYS, row)}
                                   for row in worst]
                table += "\n" + format_worst(worst)
            return _report(scores, table, args.json)
        ref_t, ref = read_trajectory(args.files[0])
        est_t, est = read_trajectory(args.files[1])
    except TrajectoryError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    s = score(ref_t, ref, est_t, est, max_dt=args.max_dt, interpolate=args.interpolate, delta=args.delta)
    if s.matched == 0:
        print(f"error: no estimate pose within {args.max_dt} s of a reference pose", file=sys.stderr)
        return 1
    code = _report(s.as_dict(), format_table(s), args.json)
    if args.plot:
        from fastslam.eval.plots import plot_errors

        try:
            plot_errors(args.plot, ref_t, ref, est_t, est, max_dt=args.max_dt, interpolate=args.interpolate,
                        title=f"{Path(args.files[1]).name} against {Path(args.files[0]).name}")
        except OSError as err:
            print(f"error: cannot write {args.plot}: {err.strerror or err}", file=sys.stderr)
            return 2
    return code


def _report(scores: dict[str, Any], table: str, as_json: bool) -> int:
    """Prints the scores; exit 1 with a clear line when one is not a number (too few
    poses for it), and JSON with null in its place (JSON has no NaN)."""
    missing = [k for k, v in scores.items() if isinstance(v, float) and not math.isfinite(v)]
    clean = {k: (None if k in missing else v) for k, v in scores.items()}
    print(json.dumps(clean, indent=2, allow_nan=False) if as_json else table)
    if missing:
        print(f"error: {', '.join(missing)} could not be computed (too few matched poses?)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
