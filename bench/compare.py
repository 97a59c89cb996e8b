"""Two sets of accuracy runs compared per log, on the seeds both have: is the difference more than the seeds' spread?

    PYTHONPATH=src:. python -m bench.compare --before A.json [A2.json ...] --after B.json [B2.json ...]

The files are `bench.accuracy --json` rows (several per side: runs split over processes or
seeds; a later file's row for the same log, seed and phase replaces an earlier one's; rows
without a phase are phase 0's). Per log, over the runs (seed and phase) both sides have:
the median of seeds 0-2 at phase 0 (the targets' runs) and of every common run, the runs over the
target (relations mean, or 0.15 m ATE) and over 0.5 m (the worst relation, or the ATE),
and p: the share of random splits of the pooled runs, into groups of the two sides' sizes,
whose medians differ at least as much in the observed direction (exact when there are few
splits). On these logs seeds differ more than most changes do (docs/benchmarks.md, round
16): judge a change on a dozen seeds or more, not on seeds 0-2.
"""
from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
from pathlib import Path
from typing import Tuple

import numpy as np

from bench.accuracy import CORRECTED, REAL, TARGET_ATE_MEDIAN, TARGET_ATE_WORST, TARGET_REL, TARGET_REL_MAX
from fastslam.cli import closed_output_ends_quietly

DRAWS = 20000          # random splits when there are more than this many


def median_shift_p(before: list[float], after: list[float], seed: int = 0, draws: int = DRAWS) -> float:
    """One-sided permutation p of the difference of medians, in the direction observed."""
    a, b = np.asarray(before, dtype=float), np.asarray(after, dtype=float)
    sign = 1.0 if np.median(a) >= np.median(b) else -1.0
    observed = sign * (np.median(a) - np.median(b))
    pool, n = np.concatenate([a, b]), len(a)
    if math.comb(len(pool), n) <= draws:     # every split
        chosen = np.array(list(itertools.combinations(range(len(pool)), n)), dtype=np.intp).reshape(-1, n)
    else:
        chosen = np.argsort(np.random.default_rng(seed).random((draws, len(pool))), axis=1)[:, :n]
    mask = np.zeros((len(chosen), len(pool)), dtype=bool)
    np.put_along_axis(mask, chosen, True, axis=1)
    rest = np.nonzero(~mask)[1].reshape(len(chosen), -1)           # each split's other side, row by row
    first, second = np.median(pool[chosen], axis=1), np.median(pool[rest], axis=1)
    return float(np.mean(sign * (first - second) >= observed - 1e-12))


Key = Tuple[str, int, int]   # log, seed, phase of the matcher's blocks (bench.phase)


def read_rows(files: list[str]) -> dict[Key, dict]:
    """(log, seed, phase) -> row, from bench.accuracy --json files."""
    rows: dict[Key, dict] = {}
    for name in files:
        try:
            data = json.loads(Path(name).read_text())
            rows.update({(str(r["log"]), int(r["seed"]), int(r.get("phase", 0))): r for r in data})
        except (OSError, ValueError, TypeError, KeyError) as err:
            raise ValueError(f"{name}: not bench.accuracy --json rows ({err})") from None
    return rows


def compare(before: dict[Key, dict], after: dict[Key, dict]) -> list[dict]:
    """Per log with common runs: seeds, phases, medians (seeds 0-2 at phase 0, all), runs over
    the target and over 0.5 m, p."""
    out = []
    for log in [*REAL, *CORRECTED]:
        keys = sorted(k for k in before if k[0] == log and k in after)
        if not keys:
            continue
        line: dict = {"log": log, "seeds": sorted({k[1] for k in keys}), "phases": sorted({k[2] for k in keys}),
                      "runs": len(keys)}
        for side, rows in (("before", before), ("after", after)):
            runs = [rows[k] for k in keys]
            err = [float(r["error"]) for r in runs]
            worst = [float(r["rel_max"]) for r in runs] if log in REAL else err
            first3 = [e for k, e in zip(keys, err) if k[1] < 3 and k[2] == 0]
            line[side] = {"errors": err, "median": float(np.median(err)),
                          "median_first3": float(np.median(first3)) if first3 else None,
                          "over_target": sum(e > TARGET_REL.get(log, TARGET_ATE_MEDIAN) for e in err),
                          "over_half_metre": sum(w > (TARGET_REL_MAX if log in REAL else TARGET_ATE_WORST)
                                                 for w in worst)}
        line["p"] = median_shift_p(line["before"]["errors"], line["after"]["errors"])
        out.append(line)
    return out


def seed_ranges(seeds: list[int]) -> str:
    """Sorted seeds as runs: [0, 1, 2, 5, 12, 13] -> "0-2, 5, 12-13"."""
    runs: list[list[int]] = []
    for s in seeds:
        if runs and s == runs[-1][-1] + 1:
            runs[-1].append(s)
        else:
            runs.append([s])
    return ", ".join(f"{r[0]}-{r[-1]}" if len(r) > 1 else f"{r[0]}" for r in runs)


def table(lines: list[dict]) -> str:
    """The comparison as a Markdown table."""
    text = ["| log | seeds | before: median 0-2 / all; over target; over 0.5 m | after: the same | p |",
            "|---|---|---|---|---|"]
    for ln in lines:
        fmt = "{:.4f}" if ln["log"] in REAL else "{:.3f}"
        cells = [f"{'-' if s['median_first3'] is None else fmt.format(s['median_first3'])} / "
                 f"{fmt.format(s['median'])}; {s['over_target']}; {s['over_half_metre']}"
                 for s in (ln["before"], ln["after"])]
        seeds = f"{len(ln['seeds'])} ({seed_ranges(ln['seeds'])})"
        if ln["phases"] != [0]:
            seeds += f" x phases {seed_ranges(ln['phases'])}: {ln['runs']} runs"
        text.append(f"| {ln['log']} | {seeds} | {cells[0]} | {cells[1]} | {ln['p']:.2f} |")
    return "\n".join(text)


@closed_output_ends_quietly
def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", nargs="+", required=True, metavar="JSON")
    ap.add_argument("--after", nargs="+", required=True, metavar="JSON")
    args = ap.parse_args(argv)
    try:
        lines = compare(read_rows(args.before), read_rows(args.after))
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if not lines:
        print("error: the two sides have no log, seed and phase in common", file=sys.stderr)
        return 2
    print(table(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
