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

import math
import sys
from typing import TYPE_CHECKING, Callable

from fastslam import offline
from fastslam.cli import closed_output_ends_quietly
from fastslam.match import matcher, search

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from fastslam.filter.grid import GridMaps

PHASES = range(search.POOL)


def shifted_window(k: int) -> Callable[[GridMaps, NDArray[np.float64], float], tuple[int, int, int, int]]:
    """search.window with its corner k cells further down and left (not below the grid's
    first cell), its far side where it was or up to a block further, its sides still
    multiples of POOL cells: the same area and more."""
    def window(grid: GridMaps, poses: NDArray[np.float64], reach: float) -> tuple[int, int, int, int]:
        x0, y0, x1, y1 = search.window(grid, poses, reach)
        h, w = grid.shape
        a0, b0 = max(x0 - k, 0), max(y0 - k, 0)
        a1 = min(w, a0 + search.POOL * math.ceil((x1 - a0) / search.POOL))
        b1 = min(h, b0 + search.POOL * math.ceil((y1 - b0) / search.POOL))
        return a0, b0, a0 + search.POOL * ((a1 - a0) // search.POOL), b0 + search.POOL * ((b1 - b0) // search.POOL)
    return window


@closed_output_ends_quietly
def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else list(argv)
    if not args or not args[0].isdigit() or int(args[0]) not in PHASES:
        got = repr(args[0]) if args else "nothing"
        print(f"bench.phase: the first argument is the phase, 0 to {PHASES[-1]}; got {got}", file=sys.stderr)
        return 2
    phase = int(args[0])
    if phase:
        matcher.window = shifted_window(phase)   # the name match_poses calls
    return offline.main(args[1:])


if __name__ == "__main__":
    sys.exit(main())
