"""The simulator node's ROS-free helpers: world and route names resolved to files (the node
itself runs in test/ros/)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from assign5.sim_node import default_worlds_dir, resolve_route, resolve_world
from fastslam.sim.world import WorldError


def test_the_package_worlds(worlds_dir):
    assert default_worlds_dir().resolve() == worlds_dir.resolve()


def test_world_by_name_file_name_or_path(worlds_dir, tmp_path):
    assert resolve_world("room", worlds_dir) == worlds_dir / "room.yaml"
    assert resolve_world("room.yaml", worlds_dir) == worlds_dir / "room.yaml"
    own = tmp_path / "mine.yaml"
    own.write_text("circles: [[1, 1, 1]]\n")
    assert resolve_world(str(own), worlds_dir) == own


def test_unknown_world_lists_the_choices_without_routes(worlds_dir):
    with pytest.raises(WorldError) as err:
        resolve_world("rooom", worlds_dir)
    message = str(err.value)
    assert "world 'rooom' is neither a file nor in" in message
    worlds = sorted(p.name[:-5] for p in worlds_dir.glob("*.yaml") if not p.name.endswith(".route.yaml"))
    assert {"office", "room", "turtlebot3_world"} <= set(worlds)
    assert f"available: {', '.join(worlds)})" in message and ".route" not in message


def test_routes_inline_by_world_name_or_path(worlds_dir, tmp_path):
    assert resolve_route("  ", worlds_dir) is None
    np.testing.assert_allclose(resolve_route("[[1, 2], [3, 4]]", worlds_dir), [[1, 2], [3, 4]])
    # a world's name means its route file, not the world file of that name
    room = resolve_route("room", worlds_dir)
    assert room.ndim == 2 and room.shape[1] == 2 and len(room) > 3
    own = tmp_path / "r.yaml"
    own.write_text("waypoints:\n  - [0.5, 0]\n")
    np.testing.assert_allclose(resolve_route(str(own), worlds_dir), [[0.5, 0.0]])
    with pytest.raises(WorldError, match="route 'nowhere' is neither a file, nor inline YAML"):
        resolve_route("nowhere", Path(worlds_dir))
