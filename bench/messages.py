"""The node's large messages (`make bench messages`): building and serialising a map of
4000 x 4000 cells and the ~trajectory of 3 hours at 10 Hz (108 000 poses), as genpy
does it (lists of Python ints, pose by pose) and as the node does (assign5/packed.py:
numpy bytes; the path's settled rows packed once, so a publication packs only the rest).

    PYTHONPATH=src:. python -m bench.messages
"""
from __future__ import annotations

import argparse
import io
import sys
import time
from typing import Any, Callable

import numpy as np

from fastslam.filter.grid import GridMaps
from fastslam.filter.history import History

POSES = 108_000   # 3 h at 10 Hz
PARTICLES = 20
MAP_CELLS = 4000


def _ms(f: Callable[[], Any], repeat: int = 3) -> float:
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - start)
    return 1000.0 * best


def _wire(msg: Any) -> int:
    buff = io.BytesIO()
    msg.serialize(buff)
    return len(buff.getvalue())


def history_of(steps: int, n: int, rng: np.random.Generator) -> History:
    """A history as a filter leaves it: resampling at every step, lineages merging."""
    h = History()
    poses = np.zeros((n, 3))
    for k in range(steps):
        poses = poses + rng.normal(0.0, 0.01, (n, 3))
        parent = np.sort(rng.integers(0, n, n)).astype(np.intp)
        h.append(0.1 * k + 1.0, poses, parent)
    return h


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args(argv)
    import rospy
    from std_msgs.msg import Header

    from assign5.convert import occupancy_msgs, path_msg
    from assign5.packed import PathCache
    from fastslam.filter.grid import logodds_to_occupancy

    rng = np.random.default_rng(0)
    grid = GridMaps(1, (MAP_CELLS, MAP_CELLS), 0.05, (0.0, 0.0))
    grid.logodds[0] = rng.integers(-127, 128, (MAP_CELLS, MAP_CELLS)).astype(np.int8)
    stamp = rospy.Time(1)

    def genpy_map() -> int:
        occ = logodds_to_occupancy(grid.logodds[0].astype(np.int16), grid.scale)   # the float formula
        msg, _ = occupancy_msgs(occ, 0.05, grid.origin, "map", stamp)
        from nav_msgs.msg import OccupancyGrid

        return _wire(OccupancyGrid(header=msg.header, info=msg.info, data=occ.ravel().tolist()))

    def packed_map() -> int:
        return _wire(occupancy_msgs(grid.occupancy(0), 0.05, grid.origin, "map", stamp)[0])

    print(f"map of {MAP_CELLS} x {MAP_CELLS} cells, built and serialised: genpy {_ms(genpy_map, 1):.0f} ms, "
          f"packed {_ms(packed_map):.0f} ms (of which the copy under the lock, occupancy by table: "
          f"{_ms(lambda: grid.occupancy(0)):.0f} ms)", flush=True)

    start = time.perf_counter()
    h = history_of(POSES, PARTICLES, rng)
    print(f"history of {POSES} updates x {PARTICLES} particles made in {time.perf_counter() - start:.1f} s "
          f"({h.settled} rows settled)", flush=True)
    header = Header(frame_id="map", stamp=stamp)
    genpy = _ms(lambda: _wire(path_msg(h.path(0), "map", stamp)), 1)
    cache = PathCache("map")
    first = _ms(lambda: _wire(cache.message(h.path(0, cache.rows), h.settled, header)), 1)
    steady = _ms(lambda: _wire(cache.message(h.path(0, cache.rows), h.settled, header)))
    print(f"~trajectory of {POSES} poses, built and serialised: genpy {genpy:.0f} ms, packed {first:.0f} ms the "
          f"first time, {steady:.1f} ms at each publication after (the lock is held only for "
          f"History.path from the packed rows on: {_ms(lambda: h.path(0, cache.rows)):.1f} ms)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
