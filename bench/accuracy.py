"""Accuracy over the whole development set, through the offline tool (`make bench accuracy`).

    PYTHONPATH=src:. python -m bench.accuracy [--config config/real.yaml] [--set key=value]... [--seeds 0 1 2]
                             [--logs csail aces intel ...] [--phases 0-3] [--jobs N] [--json FILE]
                             [--odom-noise LEVEL]

Every case runs `python -m fastslam.offline BAG --out DIR --config ... --seed S`, the
command a user runs, in its own process, one at a time (`--jobs N`: N at a time, for
judging a change on many seeds, each with `--serial`, the same results in one process;
the time targets stand only at one at a time). Seeds
are numbers or ranges: `--seeds 0-11 20`. `--phases 0-3` runs every case at each phase
of the matcher's pooling blocks (`python -m bench.phase K ...`; phase 0 is the offline
tool itself): on the two bags the seeds leave the blocks where they are, so judge a
change to the ACES bag over the phases, not over its seeds alone (round 26).

- the real robots with their own odometry at their full scan rate (`mit-csail.bag`,
  `aces.bag`), scored with their ground-truth relations (Kuemmerle et al. 2009) on the
  pose at every scan (`trajectory_scans.txt`); also on the live `map -> odom` poses and on
  `trajectory_smoothed.txt` (hindsight between processed scans: a second summary line);
- each corrected CARMEN log turned into a bag with simulated odometry noise
  (`python -m fastslam.carmen_to_bag LOG --out BAG --odom-noise 1 --seed S`), scored by the
  ATE of `trajectory_scans.txt` (and of the live and smoothed ones) against the log's poses
  (`--odom-noise 0`: the log's own poses as odometry, what the scans alone cost).

Per log: the error of each seed, their median and the worst, the worst single relation
error (relations), wall and CPU seconds of the whole command and its peak memory (the
largest over the seeds; CPU seconds stand when others share the machine); then one
summary line against the targets of issue 16.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import CancelledError, ThreadPoolExecutor
from pathlib import Path

import numpy as np

from bench.common import ROOT, data_path, progress
from bench.phase import PHASES
from fastslam.cli import closed_output_ends_quietly
from fastslam.eval.trajectory import ate, match_by_time, relations_score
from fastslam.io.trajectory_files import read_relations, read_trajectory

REAL = {"csail": "mit-csail", "aces": "aces"}          # bag + relations
CORRECTED = ("intel", "seattle", "orebro", "freiburg-101", "belgioioso", "edmonton", "acapulco")
# issue 16's targets
TARGET_REL = {"csail": 0.032, "aces": 0.045}           # relations mean [m]
TARGET_REL_MAX = 0.5                                   # any single relation [m]
TARGET_WALL = {"csail": 10.0, "aces": 15.0}            # [s]
TARGET_ATE_MEDIAN, TARGET_ATE_WORST = 0.15, 0.5        # [m]
CACHE = ROOT / "out" / "bench-accuracy"                # converted bags, reused between runs


def run_offline(bag: Path, out: Path, config: Path, seed: int, sets: list[str], phase: int = 0,
                serial: bool = False) -> dict:
    """The offline tool on bag in its own process (phase: with the matcher's blocks moved,
    bench.phase; serial: --serial, all its work in one process); its stats plus the
    command's wall time."""
    tool = ["fastslam.offline"] if phase == 0 else ["bench.phase", str(phase)]
    cmd = [sys.executable, "-m", *tool, str(bag), "--out", str(out), "--config", str(config),
           "--seed", str(seed), "--quiet"] + [a for s in sets for a in ("--set", s)] + ["--serial"] * serial
    with open(out.with_name(out.name + ".stderr"), "w+") as err:
        start = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err, env=_env())
        # reaped here for this child's own CPU time (cases may run side by side: the
        # children's total would mix them); Popen is told, so it never waits again
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - start
        proc.returncode = code = os.WEXITSTATUS(status) if os.WIFEXITED(status) else -os.WTERMSIG(status)
        err.seek(0)
        stderr = err.read()
    cpu = usage.ru_utime + usage.ru_stime
    if code != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {stderr.strip().splitlines()[-1:]}")
    stats = json.loads((out / "stats.json").read_text())
    warnings = [ln for ln in stderr.splitlines() if ln.startswith("warning")]
    return {"wall_s": wall, "cpu_s": cpu, "peak_mb": stats["peak_memory_mb"], "updates": stats["updates"],
            "scans": stats["scans"], "warnings": len(warnings)}


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), str(ROOT)])}


def converter_digest() -> str:
    """Names the converter's code, so a bag cached by an older converter is made again."""
    h = hashlib.sha256()
    for part in ("carmen_to_bag.py", "sim/odometry_noise.py", "io/carmen_log.py", "io/bag_writer.py"):
        h.update((ROOT / "src" / "fastslam" / part).read_bytes())
    return h.hexdigest()[:10]


def converted(log: str, seed: int, level: float = 1.0) -> Path:
    """The corrected log as a bag with odometry noise (level, seed), converted once."""
    bag = CACHE / f"{log}-noise{level:g}-seed{seed}-{converter_digest()}.bag"
    gt = bag.with_name(bag.name + ".gt.txt")
    if not (bag.exists() and gt.exists()):
        CACHE.mkdir(parents=True, exist_ok=True)
        # made aside and moved in, the bag last: another bench converting the same case at the
        # same time finds either no bag or a whole one (each conversion of a case is the same)
        with tempfile.TemporaryDirectory(prefix="converting-", dir=CACHE) as tmp:
            made = Path(tmp) / bag.name
            cmd = [sys.executable, "-m", "fastslam.carmen_to_bag", str(data_path(f"{log}-corrected.log.gz")),
                   "--out", str(made), "--odom-noise", f"{level:g}", "--seed", str(seed)]
            done = subprocess.run(cmd, capture_output=True, text=True, env=_env())
            if done.returncode != 0:
                raise RuntimeError(f"{' '.join(cmd)} failed: {done.stderr.strip()}")
            for part in sorted(Path(tmp).iterdir(), key=lambda p: p.name == bag.name):
                os.replace(part, CACHE / part.name)
        # the same case from an older converter is never read again: 3-6 MB a bag
        for old in CACHE.glob(f"{log}-noise{level:g}-seed{seed}-*.bag*"):
            if not old.name.startswith(bag.name):
                old.unlink(missing_ok=True)
    return bag


def real_case(name: str, seed: int, config: Path, sets: list[str], work: Path, phase: int = 0,
              serial: bool = False) -> dict:
    stem = REAL[name]
    out = work / f"{name}-{seed}-p{phase}"
    row = run_offline(data_path(f"{stem}.bag"), out, config, seed, sets, phase, serial)
    rel = read_relations(data_path(f"{stem}.relations"))
    t, p = read_trajectory(out / "trajectory_scans.txt")
    s = relations_score(t, p, rel)
    lt, lp = read_trajectory(out / "live_poses.txt")
    live = relations_score(lt, lp, rel)
    sm = relations_score(*read_trajectory(out / "trajectory_smoothed.txt"), rel)
    return {"log": name, "seed": seed, "phase": phase, "error": s.trans_mean, "rel_max": s.trans_max,
            "rot_deg": s.rot_mean,
            "live": live.trans_mean, "live_max": live.trans_max, "smoothed": sm.trans_mean,
            "smoothed_max": sm.trans_max, **row}


def corrected_case(name: str, seed: int, config: Path, sets: list[str], work: Path, phase: int = 0,
                   serial: bool = False, noise: float = 1.0) -> dict:
    bag = converted(name, seed, noise)
    out = work / f"{name}-{seed}-p{phase}"
    row = run_offline(bag, out, config, seed, sets, phase, serial)
    ref_t, ref = read_trajectory(bag.with_name(bag.name + ".gt.txt"))
    t, p = read_trajectory(out / "trajectory_scans.txt")
    _, r, e = match_by_time(ref_t, ref, t, p, max_dt=1e-4)
    lt, lp = read_trajectory(out / "live_poses.txt")
    _, lr, le = match_by_time(ref_t, ref, lt, lp, max_dt=1e-4)
    _, sr, se = match_by_time(ref_t, ref, *read_trajectory(out / "trajectory_smoothed.txt"), max_dt=1e-4)
    return {"log": name, "seed": seed, "phase": phase, "error": ate(r, e), "matched": len(r), "live": ate(lr, le),
            "smoothed": ate(sr, se), **row}


def print_log(rows: list[dict], relations: bool, phases: bool = False) -> None:
    """One log's table line (phases: one phase's, named so)."""
    err = [r["error"] for r in rows]
    seeds = " ".join(f"{v:6.3f}" for v in err)
    extra = f"{max(r['rel_max'] for r in rows):8.3f}" if relations else f"{'':8}"
    live = np.median([r["live"] for r in rows])
    smooth = np.median([r["smoothed"] for r in rows])
    name = f"{rows[0]['log']} p{rows[0]['phase']}" if phases else rows[0]["log"]
    print(f"{name:<13} {'rel' if relations else 'ATE':<4} {seeds:<21} {np.median(err):7.3f} "
          f"{max(err):7.3f} {extra} {live:7.3f} {smooth:8.3f} {max(r['wall_s'] for r in rows):7.1f} "
          f"{max(r['cpu_s'] for r in rows):6.1f} "
          f"{max(r['peak_mb'] for r in rows):7.0f} {rows[0]['updates']:>5}/{rows[0]['scans']:<5}", flush=True)


def summary(rows: list[dict], error: str = "error", rel_max: str = "rel_max", title: str = "summary") -> str:
    """One line, worst case first: each target's figure and whether it is met (on the
    trajectory whose scores are error and rel_max: trajectory_scans.txt's, or the smoothed one's)."""
    def by(log: str) -> list[dict]:
        return [r for r in rows if r["log"] == log]

    parts, met, total = [], 0, 0
    checks = []
    for name in REAL:
        rs = by(name)
        if rs:
            checks.append((f"{name} rel mean worst", max(r[error] for r in rs), TARGET_REL[name]))
            checks.append((f"{name} rel max", max(r[rel_max] for r in rs), TARGET_REL_MAX))
            checks.append((f"{name} wall", max(r["wall_s"] for r in rs), TARGET_WALL[name]))
    logs = [n for n in CORRECTED if by(n)]
    if logs:
        worst_median = max(logs, key=lambda n: np.median([r[error] for r in by(n)]))
        checks.append((f"ATE median worst ({worst_median})",
                       float(np.median([r[error] for r in by(worst_median)])), TARGET_ATE_MEDIAN))
        worst = max((r for r in rows if r["log"] in logs), key=lambda r: r[error])
        checks.append((f"ATE run worst ({worst['log']} seed {worst['seed']})", worst[error], TARGET_ATE_WORST))
    checks.sort(key=lambda c: -c[1] / c[2])  # worst ratio to its target first
    for label, value, target in checks:
        total += 1
        ok = value <= target
        met += ok
        parts.append(f"{label} {value:.3f} ({'ok' if ok else 'over'} {target:g})")
    return f"{title}: {met}/{total} targets met; " + "; ".join(parts)


def seed_list(words: list[str], what: str = "seed", flag: str = "--seeds") -> list[int]:
    """Seeds (or other numbers) from numbers and ranges ("0-11": 0 to 11), in the order given."""
    seeds: list[int] = []
    for word in words:
        first, dash, last = word.partition("-")
        if not first.isdigit() or (dash and not last.isdigit()) or (dash and int(last) < int(first)):
            raise ValueError(f"{flag}: {word!r} is neither a {what} nor a range such as 0-11")
        seeds += list(range(int(first), int(last if dash else first) + 1))
    return seeds


def run_cases(logs: list[str], seeds: list[int], config: Path, sets: list[str], work: Path,
              jobs: int, phases: list[int] | None = None, noise: float = 1.0) -> list[dict]:
    """Every (log, phase, seed) case, jobs at a time; each log's (and phase's) table line
    printed once its cases are done, the logs, phases and seeds in the order given; the
    corrected logs with odometry noise of that level."""
    failed = threading.Event()   # a failed case stops the bench: no case starts after it
    phases = [0] if phases is None else list(dict.fromkeys(phases))   # each phase once: one line each

    def case(name: str, seed: int, phase: int) -> dict:
        if failed.is_set():   # (the bench meets the failure before any case skipped after it)
            raise CancelledError(f"{name} seed {seed}{f' phase {phase}' if phase else ''}: not run after a failed case")
        try:
            # cases side by side keep the cores busy: each runs in one process (the same results)
            if name in REAL:
                return real_case(name, seed, config, sets, work, phase, jobs > 1)
            return corrected_case(name, seed, config, sets, work, phase, jobs > 1, noise)
        except BaseException:
            failed.set()
            raise

    rows: list[dict] = []
    with ThreadPoolExecutor(max_workers=jobs) as pool:   # threads: each only waits on its process
        pending = {(name, phase): [pool.submit(case, name, seed, phase) for seed in seeds]
                   for name in logs for phase in phases}
        try:
            for name, phase in pending:
                label = name if phases == [0] else f"{name} phase {phase}"
                log_rows = [f.result() for f in progress(pending[(name, phase)], label)]
                rows += log_rows
                print_log(log_rows, name in REAL, phases != [0])
        except BaseException:
            failed.set()   # (an interrupt here too) the cases not yet started end at once
            raise
    return rows


@closed_output_ends_quietly
def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", default=str(ROOT / "config" / "real.yaml"))
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="passed to the offline tool")
    ap.add_argument("--seeds", nargs="+", default=["0", "1", "2"], help="seeds and ranges (0-11)")
    ap.add_argument("--logs", nargs="+", default=list(REAL) + list(CORRECTED), choices=list(REAL) + list(CORRECTED))
    ap.add_argument("--phases", nargs="+", default=["0"],
                    help=f"phases of the matcher's pooling blocks, 0-{PHASES[-1]} (bench.phase; default 0)")
    ap.add_argument("--jobs", type=int, default=1, help="cases run at once (time targets: 1)")
    ap.add_argument("--json", metavar="FILE", help="also write every row here")
    ap.add_argument("--odom-noise", type=float, default=1.0, metavar="LEVEL",
                    help="the corrected logs' simulated odometry noise (default 1, issue 16's targets; 0: the "
                         "log's own poses as odometry, what the scans alone cost)")
    args = ap.parse_args(argv)
    try:
        args.seeds = seed_list(args.seeds)
        args.phases = seed_list(args.phases, "phase", "--phases")
    except ValueError as err:
        ap.error(str(err))
    outside = [p for p in args.phases if p not in PHASES]
    if outside:
        ap.error(f"--phases: {outside[0]} is not a phase of the matcher's blocks (0 to {PHASES[-1]})")
    if args.jobs < 1:
        ap.error(f"--jobs: {args.jobs} is not a number of cases at once (1 or more)")
    if not args.odom_noise >= 0.0:   # (nan too)
        ap.error(f"--odom-noise: {args.odom_noise:g} is not a noise level (0 or more)")
    config = Path(args.config).resolve()
    shown = config.relative_to(ROOT) if ROOT in config.parents else config  # no is_relative_to on 3.8
    print(f"accuracy: {shown}"
          f"{' ' + ' '.join(args.set) if args.set else ''}, seeds {args.seeds}"
          f"{f', phases {args.phases}' if args.phases != [0] else ''}"
          f"{f', odometry noise {args.odom_noise:g}' if args.odom_noise != 1.0 else ''}"
          f", data {data_path('aces.bag').parent}"
          f"{f', {args.jobs} cases at once (wall and CPU seconds share the machine)' if args.jobs > 1 else ''}")
    print("rel: relations mean [m] of the pose at every scan (max: worst single relation); ATE [m] after "
          "alignment; live: the same for map->odom's poses (median); smoothed: the same for "
          "trajectory_smoothed.txt's (median, hindsight between processed scans); wall s, cpu s (user + "
          "system) and peak MB: whole command, largest over the seeds")
    print(f"{'log':<13} {'':<4} {'seeds':<21} {'median':>7} {'worst':>7} {'max rel':>8} {'live':>7} "
          f"{'smoothed':>8} "
          f"{'wall s':>7} {'cpu s':>6} {'peak MB':>7} {'updates/scans'}")
    with tempfile.TemporaryDirectory(prefix="bench-accuracy-") as tmp:
        try:
            rows = run_cases(args.logs, args.seeds, config, args.set, Path(tmp), args.jobs, args.phases,
                             args.odom_noise)
        except RuntimeError as err:   # a case's command failed: its last line, no traceback
            print(f"bench.accuracy: {err}", file=sys.stderr)
            return 1
    print(summary(rows))
    print(summary(rows, "smoothed", "smoothed_max", "smoothed"))
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
