"""Unit-test data shared by several files: a relations case worked by hand
(eval/test_trajectory.py, test_evaluate.py)."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

# A hand-made relations case. Estimate: (0, 0, 0) at t=0, (1, 0, pi/2) at 1, (1, 1, pi/2) at 2.
_T = np.array([0.0, 1.0, 2.0])
_POSES = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, math.pi / 2], [1.0, 1.0, math.pi / 2]])
# 1: t1 = 0.5 -> (0.5, 0, pi/4) interpolated; t2 = 2.5 -> (1, 1, pi/2) clamped. Seen from the
#    first: ((0.5 + 1) / sqrt2, (-0.5 + 1) / sqrt2, pi/4) = (1.5, 0.5, pi/4) / sqrt2 in x, y.
#    Expected (1, 0, 0): error = est (+) (-1, 0, 0) = est - (cos pi/4, sin pi/4) in x, y
#    = (0.5, -0.5) / sqrt2: translation 0.5 m, rotation 45 deg. (The other order,
#    expected^-1 est, would give |(1.5 / sqrt2 - 1, 0.5 / sqrt2)| = 0.359 m.)
# 2: t1 = -1 -> (0, 0, 0) clamped, t2 = 1 -> (1, 0, pi/2), expected (1, 0, pi/2): error 0.
_RELATIONS = "0.5 2.5 1 0 0 0 0 0\n-1 1 1 0 0 0 0 1.5707963267948966\n"


@pytest.fixture
def relations_case(tmp_path) -> SimpleNamespace:
    """t (3,), poses (3, 3) of an estimate, and a file r.relations of two relations against it
    whose errors are 0.5 m / 45 deg and 0 (worked out above)."""
    path = tmp_path / "r.relations"
    path.write_text(_RELATIONS)
    return SimpleNamespace(t=_T.copy(), poses=_POSES.copy(), path=path)
