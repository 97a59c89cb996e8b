"""The scan matcher on its own: how far from the reference pose does a match land?

One particle's map is built from the reference poses (no filter, no noise); every
processed scan is then matched against it, starting from the reference pose moved by
an odometry error and a sampling error, each drawn from the motion model's spread for
that step (seeded). The matcher sees the same prior as in the filter (centred on the
erring prediction, or the window prior round the sample). Prints the bias and spread of matched - reference in the robot
frame, which the filter's chaotic end results cannot show.

    python -m bench.matcher [intel|office] [--config FILE] [--limit 400] [--set key=value]...

The preset measured is the one for the data's laser: config/real.yaml on Intel,
config/burger.yaml (the LDS-01's) on the office, unless --config names another.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Iterator

import numpy as np

from bench.common import data_path
from fastslam.config import SlamConfig, parse_override
from fastslam.filter.motion import odometry_std
from fastslam.filter.proposal import gate_match, match_request
from fastslam.filter.scan import Scan, select_beams
from fastslam.filter.slam import FastSlam
from fastslam.geometry import compose, relative
from fastslam.match import MatchParams, match_poses

ROOT = Path(__file__).resolve().parents[1]
PRESETS = {"intel": ROOT / "config" / "real.yaml", "office": ROOT / "config" / "burger.yaml"}


def intel_scans(limit: int | None) -> Iterator[tuple[np.ndarray, Scan]]:
    """(reference pose, scan) of the Intel log's FLASER records."""
    from fastslam.io.carmen_log import read_log

    for rec in read_log(data_path("intel-corrected.log.gz"), limit=limit).scans:
        yield np.asarray(rec.robot_pose, dtype=float), Scan.from_laser(
            rec.ranges.astype(np.float64), rec.angle_min, rec.angle_increment, 0.0, rec.max_range,
            mount=rec.mount, stamp=rec.t)


def office_scans(limit: int | None) -> Iterator[tuple[np.ndarray, Scan]]:
    """(true pose, scan) of the simulator's office route, perfect odometry."""
    from fastslam.eval.trajectory import match_by_time
    from fastslam.simrun import run

    cfg = SlamConfig.from_yaml(PRESETS["office"], {"proposal": "odometry", "toggle_noise": 0, "particles": 1})
    sim = run("office", cfg, seed=0, sim={"odom_noise": False}, record=True)
    for rec in sim.scans[:limit]:
        pose = match_by_time(sim.truth[:, 0], sim.truth[:, 1:], [rec.t], np.zeros((1, 3)), interpolate=True)[1][0]
        yield pose, Scan.from_laser(rec.ranges, rec.angle_min, rec.angle_increment, rec.range_min,
                                    rec.range_max, mount=sim.mount, stamp=rec.t)


def match_errors(cfg: SlamConfig, scans: Iterator[tuple[np.ndarray, Scan]], seed: int = 0) -> np.ndarray:
    """(K, 3) matched - reference (along, across [m], heading [rad]) of trusted matches."""
    # The map is written at the reference poses: one particle moved exactly by them.
    mapper = FastSlam(cfg.replace(particles=1, proposal="odometry", motion_model="odometry", toggle_noise=0,
                                track_scans=False))
    params = MatchParams.from_config(cfg)
    rng = np.random.default_rng(seed)
    alphas = (cfg.srr, cfg.srt, cfg.str, cfg.stt)
    out, last = [], None
    for pose, scan in scans:
        if last is not None and not mapper.due(pose, scan.stamp):
            continue
        if last is not None:
            std = np.maximum(odometry_std(last, pose, alphas), 1e-9)
            predicted = compose(pose, rng.normal(0.0, 1.0, 3) * std)      # where odometry says
            sample = compose(predicted, rng.normal(0.0, 1.0, 3) * std)    # the particle's sample
            start, step_params, prior = match_request(cfg, params, sample[None], predicted[None], std)
            match = match_poses(mapper.grid, start, select_beams(scan, cfg), step_params, prior=prior)
            match = gate_match(cfg, match, predicted[None], std)                  # as FastSlam does
            if match.trusted[0]:
                out.append(relative(pose, match.poses[0]))
        mapper.step(pose, scan)
        last = pose
    return np.array(out).reshape(-1, 3)


def summary(err: np.ndarray) -> str:
    xy = np.hypot(err[:, 0], err[:, 1])
    mm = 1000.0
    return (f"{len(err)} matches: bias along {mm * err[:, 0].mean():+.1f} mm, across {mm * err[:, 1].mean():+.1f} mm, "
            f"heading {mm * err[:, 2].mean():+.2f} mrad; RMS along {mm * np.sqrt(np.mean(err[:, 0] ** 2)):.1f} mm, "
            f"across {mm * np.sqrt(np.mean(err[:, 1] ** 2)):.1f} mm, "
            f"heading {mm * np.sqrt(np.mean(err[:, 2] ** 2)):.1f} "
            f"mrad; median {mm * np.median(xy):.1f} mm, > 10 cm {100 * np.mean(xy > 0.1):.1f} %")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", nargs="?", default="intel", choices=("intel", "office"))
    parser.add_argument("--config", type=Path, help="default: the data's preset (real.yaml, burger.yaml)")
    parser.add_argument("--limit", type=int, default=None, help="first scans of the data only")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args(argv)
    config = args.config or PRESETS[args.data]
    cfg = SlamConfig.from_yaml(config, dict(parse_override(s) for s in args.set))
    scans = intel_scans(args.limit) if args.data == "intel" else office_scans(args.limit)
    print(f"{args.data} ({config.name}): {summary(match_errors(cfg, scans, args.seed))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
