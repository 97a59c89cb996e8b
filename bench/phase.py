"""The offline tool with the matcher's pooling blocks moved (`bench.accuracy --phases`).

    PYTHONPATH=src:. python -m bench.phase K BAG --out DIR [the offline tool's options]

The coarse searches pool each map into blocks of 2x2 and 4x4 cells from the corner of a
window round the particles. On a bag with its own odometry the seeds change only the
filter's draws, so the blocks fall alike at every seed, and a few seeds of the ACES bag
can all win or all lose by where they fall (docs/benchmarks.md, round 26). Phase K
(0 to POOL - 1) moves that corner K cells down and left: the same run with the blocks
elsewhere. Phase 0 is the offline tool itself.
"""
from __future__ import annotations

import functools
import sys

from fastslam import offline
from fastslam.cli import closed_output_ends_quietly
from fastslam.match import matcher, search

PHASES = range(search.POOL)


@closed_output_ends_quietly
def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else list(argv)
    if not args or not args[0].isdigit() or int(args[0]) not in PHASES:
        got = repr(args[0]) if args else "nothing"
        print(f"bench.phase: the first argument is the phase, 0 to {PHASES[-1]}; got {got}", file=sys.stderr)
        return 2
    phase = int(args[0])
    if phase:
        matcher.window = functools.partial(search.window, shift=phase)   # the name match_poses calls
    return offline.main(args[1:])


if __name__ == "__main__":
    sys.exit(main())
