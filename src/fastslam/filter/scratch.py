"""Reused work arrays for the hot paths of the filter and the matcher."""
from __future__ import annotations

import math
import threading
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


_scratch = threading.local()


def scratch(key: str, shape: tuple[int, ...], dtype: Any) -> NDArray[Any]:
    """A work array of this shape, contents undefined, reused by the next call with
    the same key (per thread): a large temporary allocated afresh every scan costs a
    page fault per 4 KiB page, which in a VM costs more than the arithmetic on it."""
    arrays = _scratch.__dict__.setdefault("arrays", {})
    size = math.prod(shape)
    buf = arrays.get(key)
    if buf is None or buf.dtype != dtype or buf.size < size:
        buf = arrays[key] = np.empty(size + size // 4, dtype)  # headroom: sizes vary a little
    return buf[:size].reshape(shape)
