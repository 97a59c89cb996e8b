"""Maps pooled to 2x2 and 4x4 blocks of cells, the matcher's coarse levels.

A pooled cell is the sign of its block's largest log-odds: +1 where any cell of the
block is occupied, -1 where every cell is known free, 0 otherwise (pool_signed), or
only whether any is occupied (pool_occupied).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Tuple

import numpy as np

from fastslam.filter.scratch import scratch

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray

    Pooled = Tuple[NDArray[np.int8], NDArray[np.int8]]   # (2x2, 4x4 cells)


POOL = 4               # cells per side of the coarsest block
POOL_CELLS = 1 << 20   # cells pooled at a time (maps x window): the work arrays stay small


def pool_occupied(level: NDArray[np.int8], above: int = 0, out: Pooled | None = None) -> Pooled:
    """(N, H, W) -> 0/1 flags (N, H/2, W/2) and (N, H/4, W/4): whether any cell of each
    2x2 and 4x4 block is occupied (log-odds above `above`; H, W multiples of 4); out:
    the arrays to write them to.

    Any cell above `above` is the block's maximum above it (see block_max).
    """
    m2 = block_max(level, "pool2")
    half, quarter = (None, None) if out is None else (out[0].view(np.bool_), out[1].view(np.bool_))
    return (np.greater(m2, above, out=half).view(np.int8),
            np.greater(block_max(m2, "pool4"), above, out=quarter).view(np.int8))


def pool_signed(level: NDArray[np.int8], out: Pooled | None = None) -> Pooled:
    """(N, H, W) -> (N, H/2, W/2) and (N, H/4, W/4): +1 where any cell of the 2x2 or 4x4
    block is occupied, -1 where every cell is known free, 0 otherwise (H, W multiples of 4);
    out: the arrays to write them to.

    An end point on a free block contradicts the map (the beam would have ended
    there before): summed, these flags score a candidate by the end points it puts on
    walls less those it puts in free space, which a wrong alignment (a turned copy of
    a room, the wrong side of a wall) cannot hide. They are the sign of the block's
    maximum: above 0 if any cell is occupied, below 0 if every cell is free.
    """
    m2 = block_max(level, "pool2")
    half, quarter = (None, None) if out is None else out
    return np.sign(m2, out=half), np.sign(block_max(m2, "pool4"), out=quarter)


def block_max(level: NDArray[np.int8], key: str) -> NDArray[np.int8]:
    """(k, H, W) -> (k, H/2, W/2) maxima of 2x2 blocks, in a reused work array: row pairs
    first (whole rows), then the two bytes of each column pair."""
    k, h, w = level.shape
    rows = np.maximum(level[:, 0::2, :], level[:, 1::2, :], out=scratch(key + "_rows", (k, h // 2, w), np.int8))
    pairs = rows.reshape(k, h // 2, w // 2, 2)
    return np.maximum(pairs[..., 0], pairs[..., 1], out=scratch(key, (k, h // 2, w // 2), np.int8))
