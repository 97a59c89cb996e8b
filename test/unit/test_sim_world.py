"""World loading, validation errors, PGM maps, clearance and boundary sampling."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fastslam.sim.world import World, WorldError, inside_polygon, world_from_dict
from fastslam.sim.world_loader import load_world, mask_segments

WORLDS = Path(__file__).resolve().parents[2] / "worlds"


@pytest.mark.parametrize("name", ["turtlebot3_world", "room", "office"])
def test_shipped_worlds_load_with_free_spawn(name: str) -> None:
    w = load_world(WORLDS / f"{name}.yaml")
    assert w.segments.shape[1:] == (2, 2) and w.circles.shape[1:] == (3,)
    assert w.clearance(w.spawn[None, :2])[0] > 0.3


def test_turtlebot3_world_geometry() -> None:
    w = load_world(WORLDS / "turtlebot3_world.yaml")
    np.testing.assert_allclose(w.spawn, [-2.0, -0.5, 0.0])
    assert len(w.circles) == 9
    np.testing.assert_allclose(np.unique(w.circles[:, 0]), [-1.1, 0.0, 1.1])
    np.testing.assert_allclose(w.circles[:, 2], 0.15)
    arena = w.polygons[0]
    np.testing.assert_allclose(np.hypot(arena[:, 0], arena[:, 1]), 2.93)
    np.testing.assert_allclose(arena[0], [2.93, 0.0], atol=1e-12)     # a corner on +x
    assert w.solid == [False, True, True, True, True, True]


def test_bounds_and_room_size() -> None:
    xmin, ymin, xmax, ymax = load_world(WORLDS / "room.yaml").bounds()
    assert (xmin, ymin, xmax, ymax) == (-3.0, -3.0, 3.0, 3.0)
    xmin, ymin, xmax, ymax = load_world(WORLDS / "office.yaml").bounds()
    assert (xmax - xmin, ymax - ymin) == (20.0, 15.0)


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


def test_missing_and_invalid_files(tmp_path: Path) -> None:
    with pytest.raises(WorldError, match="cannot read"):
        load_world(tmp_path / "nope.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("segments: [[[0, 0], [1, 1]]\n")
    with pytest.raises(WorldError, match="not valid YAML"):
        load_world(bad)


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


def _write_map(tmp_path: Path, pixels: np.ndarray, origin: str = "[-1.0, -2.0, 0.0]") -> Path:
    h, w = pixels.shape
    (tmp_path / "m.pgm").write_bytes(b"P5\n# CREATOR: test 0.5 m/pix\n%d %d\n255\n" % (w, h) + pixels.tobytes())
    y = tmp_path / "m.yaml"
    y.write_text(f"image: m.pgm\nresolution: 0.5\norigin: {origin}\nnegate: 0\n"
                 "occupied_thresh: 0.65\nfree_thresh: 0.196\nspawn: [0.25, -1.25, 90]\n")
    return y


def test_pgm_map_single_pixel_becomes_a_square(tmp_path: Path) -> None:
    px = np.full((3, 4), 254, np.uint8)
    px[0, 1] = 0                         # top row, column 1 -> cell x in [-0.5, 0], y in [-1.0, -0.5]
    w = load_world(_write_map(tmp_path, px))
    assert len(w.segments) == 4
    pts = w.segments.reshape(-1, 2)
    np.testing.assert_allclose(pts.min(axis=0), [-0.5, -1.0])
    np.testing.assert_allclose(pts.max(axis=0), [0.0, -0.5])
    np.testing.assert_allclose(w.spawn, [0.25, -1.25, math.pi / 2])


def test_pgm_runs_are_merged_and_header_checked(tmp_path: Path) -> None:
    occ = np.zeros((4, 6), bool)
    occ[1, :] = True                     # one wall of 6 pixels -> 4 segments, not 24
    assert len(mask_segments(occ, 0.1, (0.0, 0.0, 0.0))) == 4
    y = _write_map(tmp_path, np.zeros((2, 2), np.uint8))
    (tmp_path / "m.pgm").write_bytes(b"P5\n4 4\n255\n\0\0\0")    # 3 of the 16 pixels
    with pytest.raises(WorldError, match="image: cannot read image .*m.pgm"):
        load_world(y)
    y = _write_map(tmp_path, np.zeros((2, 2), np.uint8))
    y.write_text(y.read_text().replace("resolution: 0.5", "resolution: -1"))
    with pytest.raises(WorldError, match="resolution"):
        load_world(y)


def test_empty_world_is_allowed_programmatically() -> None:
    assert np.isinf(World().clearance(np.zeros((1, 2)))).all()
