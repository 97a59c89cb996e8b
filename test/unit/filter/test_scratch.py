"""scratch: work arrays reused by key, shape, dtype and thread."""
from __future__ import annotations

import threading

import numpy as np

from fastslam.filter.scratch import scratch


def address(a: np.ndarray) -> int:
    return a.__array_interface__["data"][0]


def test_same_key_reuses_the_memory_and_sizes_follow_the_request():
    a = scratch("test_scratch_reuse", (4, 25), np.float32)
    assert a.shape == (4, 25) and a.dtype == np.float32
    a[:] = 7.0
    b = scratch("test_scratch_reuse", (100,), np.float32)
    assert address(b) == address(a) and np.all(b == 7.0)   # contents carry over: "undefined" to callers
    c = scratch("test_scratch_reuse", (5, 5), np.float32)  # smaller: the same memory
    assert c.shape == (5, 5) and address(c) == address(a)


def test_growth_within_the_headroom_reuses_beyond_it_reallocates():
    a = scratch("test_scratch_grow", (100,), np.int16)      # 100 + 25 elements allocated
    assert address(scratch("test_scratch_grow", (125,), np.int16)) == address(a)
    b = scratch("test_scratch_grow", (126,), np.int16)
    assert address(b) != address(a) and b.shape == (126,)
    # the new buffer (126 + 31) holds the next 157 elements without a new allocation
    assert address(scratch("test_scratch_grow", (157,), np.int16)) == address(b)


def test_another_dtype_or_key_gets_its_own_array():
    a = scratch("test_scratch_kind", (10,), np.int8)
    b = scratch("test_scratch_kind", (10,), np.int32)
    assert b.dtype == np.int32 and not np.shares_memory(a, b)
    c = scratch("test_scratch_other", (10,), np.int32)
    assert not np.shares_memory(b, c)


def test_each_thread_has_its_own_arrays():
    mine = scratch("test_scratch_thread", (64,), np.float64)
    theirs = []
    t = threading.Thread(target=lambda: theirs.append(scratch("test_scratch_thread", (64,), np.float64)))
    t.start()
    t.join()
    assert not np.shares_memory(mine, theirs[0])
    assert address(scratch("test_scratch_thread", (64,), np.float64)) == address(mine)
