"""Fixtures shared by the unit and integration tests: the repository and its worlds, the
pillar room and scans of it cast by the simulator's exact lidar, and seeded generators
(the development data: test/integration/conftest.py)."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Callable

import numpy as np
import pytest

from fastslam.filter.scan import Scan
from fastslam.sim.lidar import cast_rays
from fastslam.sim.world import World
from fastslam.sim.world_loader import load_world

ROOT = Path(__file__).resolve().parents[1]

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import ArrayLike, NDArray

    RoomRanges = Callable[[ArrayLike, ArrayLike], NDArray[np.float64]]


@pytest.fixture(scope="session")
def repo_root() -> Path:
    """The repository (config/, worlds/, src/ ...)."""
    return ROOT


@pytest.fixture(scope="session")
def worlds_dir() -> Path:
    return ROOT / "worlds"


@pytest.fixture(scope="session")
def pillar_room() -> World:
    """worlds/pillar_room.yaml: a bare 5 m x 5 m room (walls at +-2.5 m) with a pillar of
    radius 0.3 m at (1, 1)."""
    return load_world(ROOT / "worlds" / "pillar_room.yaml")


@pytest.fixture(scope="session")
def room_ranges(pillar_room: World) -> RoomRanges:
    """room_ranges(pose (3,), angles (M,)) -> (M,) exact ranges in the pillar room from the
    simulator's lidar (segments and circles intersected analytically, not the grid)."""
    def ranges(pose: ArrayLike, angles: ArrayLike) -> NDArray[np.float64]:
        return cast_rays(pillar_room, pose, angles)

    return ranges


@pytest.fixture(scope="session")
def room_scan(room_ranges: RoomRanges) -> Callable[..., Scan]:
    """room_scan(pose, angles, stamp=0.0) -> the exact Scan of the pillar room from pose,
    an LDS-01's limits (0.12 .. 3.5 m)."""
    def scan(pose: ArrayLike, angles: NDArray[np.float64], stamp: float = 0.0) -> Scan:
        return Scan(ranges=room_ranges(pose, angles), angles=angles, range_min=0.12, range_max=3.5, stamp=stamp)

    return scan


@pytest.fixture
def rng() -> np.random.Generator:
    """A generator seeded 0, fresh for every test."""
    return np.random.default_rng(0)
