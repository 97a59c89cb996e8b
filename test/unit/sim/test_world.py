"""Worlds of exact primitives: validation errors naming the field, clearance, boundary sampling."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.sim.world import World, WorldError, inside_polygon, polygon_segments, regular_polygon, world_from_dict


@pytest.mark.parametrize("data, field", [
    ({"segments": [[[0, 0], [1]]]}, "segments[0]"),
    ({"circles": [[0, 0, -1]]}, "circles[0].r"),
    ({"circles": [[0, 0]]}, "circles[0]"),
    ({"polygons": [[[0, 0], [1, 0]]]}, "polygons[0]"),
    ({"polygons": [{"center": [0, 0], "radius": 1, "sides": 2}]}, "polygons[0].sides"),
    ({"polygons": [{"center": [0, 0], "radius": 1, "colour": 2}]}, "polygons[0].colour"),
    ({"segments": [[[5, -1], [5, 1]]], "spawn": [0, "a", 0]}, "spawn[1]"),
    ({"segments": [[[0, -1], [0, 1]]], "spawn": [0, 0, 0]}, "spawn"),
    ({"polygons": [[[-1, -1], [1, -1], [1, 1]]], "spawn": [0.5, -0.5, 0]}, "spawn"),
    ({"circles": [[0, 0, 1]], "spawn": [0.2, 0, 0]}, "spawn"),
    ({"segmnets": []}, "segmnets"),
    ({}, "no geometry"),
])
def test_bad_fields_are_named(data: dict, field: str) -> None:
    with pytest.raises(WorldError, match=__import__("re").escape(field)):
        world_from_dict(data)


def test_clearance_hand_computed() -> None:
    w = world_from_dict({"segments": [[[0, -1], [0, 1]]], "circles": [[5, 0, 1]], "spawn": [2, 0, 0]})
    np.testing.assert_allclose(w.clearance(np.array([[2.0, 0.0], [0.0, 3.0], [5.0, 0.0]])), [2.0, 2.0, 1.0])


def test_sample_boundary_spacing_and_hidden_parts() -> None:
    w = world_from_dict({"segments": [[[0, 0], [1, 0]]], "circles": [[3, 0, 0.5]], "spawn": [0, 1, 0]})
    pts = w.sample_boundary(0.1)
    on_seg = pts[(np.abs(pts[:, 1]) < 1e-12) & (pts[:, 0] < 2)]
    assert len(on_seg) == 11 and np.allclose(np.diff(np.sort(on_seg[:, 0])), 0.1)
    ring = pts[pts[:, 0] > 2]
    np.testing.assert_allclose(np.hypot(ring[:, 0] - 3, ring[:, 1]), 0.5)
    # a solid square half outside the enclosure: its outer half and the wall inside it vanish
    w2 = world_from_dict({"polygons": [{"points": [[-2, -2], [2, -2], [2, 2], [-2, 2]], "solid": False},
                                       [[1.5, -0.5], [2.5, -0.5], [2.5, 0.5], [1.5, 0.5]]]})
    p2 = w2.sample_boundary(0.05)
    assert p2[:, 0].max() <= 2.0 + 1e-9
    assert not ((p2[:, 0] > 1.5 + 1e-9) & (np.abs(p2[:, 1]) < 0.5 - 1e-9)).any()


def test_inside_polygon() -> None:
    sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    assert inside_polygon(np.array([[0.5, 0.5], [1.5, 0.5], [-0.1, 0.2]]), sq).tolist() == [True, False, False]


def test_empty_world_is_allowed_programmatically() -> None:
    assert np.isinf(World().clearance(np.zeros((1, 2)))).all()


def test_regular_polygon_and_its_segments() -> None:
    square = regular_polygon((1.0, 2.0), np.sqrt(2.0), 4, yaw_deg=45.0)   # circumradius sqrt 2: a 2 m square
    np.testing.assert_allclose(square, [[2, 3], [0, 3], [0, 1], [2, 1]], atol=1e-12)
    segs = polygon_segments(square)
    assert segs.shape == (4, 2, 2)
    np.testing.assert_allclose(segs[3], [[2, 1], [2, 3]], atol=1e-12)     # closed: the last edge returns


def test_polygons_circles_and_spawn_from_a_dict() -> None:
    w = world_from_dict({"polygons": [{"center": [0, 0], "radius": 1, "sides": 6}], "circles": [[5, 0, 0.5]],
                         "spawn": [3, 0, 90]}, name="hex")
    assert w.name == "hex" and len(w.segments) == 6 and w.solid == [True]
    np.testing.assert_allclose(w.spawn, [3.0, 0.0, np.pi / 2])           # yaw in degrees in the file
    np.testing.assert_allclose(w.bounds(), (-1.0, -np.sqrt(0.75), 5.5, np.sqrt(0.75)))
