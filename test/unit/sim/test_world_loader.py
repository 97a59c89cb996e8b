"""Worlds from files: world YAMLs (the shipped worlds) and map_server maps whose occupied
pixels become wall segments."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fastslam.sim.world import WorldError
from fastslam.sim.world_loader import load_world, mask_segments


@pytest.mark.parametrize("name", ["turtlebot3_world", "room", "office"])
def test_shipped_worlds_load_with_free_spawn(name: str, worlds_dir: Path) -> None:
    w = load_world(worlds_dir / f"{name}.yaml")
    assert w.segments.shape[1:] == (2, 2) and w.circles.shape[1:] == (3,)
    assert w.clearance(w.spawn[None, :2])[0] > 0.3


def test_turtlebot3_world_geometry(worlds_dir: Path) -> None:
    w = load_world(worlds_dir / "turtlebot3_world.yaml")
    np.testing.assert_allclose(w.spawn, [-2.0, -0.5, 0.0])
    assert len(w.circles) == 9
    np.testing.assert_allclose(np.unique(w.circles[:, 0]), [-1.1, 0.0, 1.1])
    np.testing.assert_allclose(w.circles[:, 2], 0.15)
    arena = w.polygons[0]
    np.testing.assert_allclose(np.hypot(arena[:, 0], arena[:, 1]), 2.93)
    np.testing.assert_allclose(arena[0], [2.93, 0.0], atol=1e-12)     # a corner on +x
    assert w.solid == [False, True, True, True, True, True]


def test_bounds_and_room_size(worlds_dir: Path) -> None:
    xmin, ymin, xmax, ymax = load_world(worlds_dir / "room.yaml").bounds()
    assert (xmin, ymin, xmax, ymax) == (-3.0, -3.0, 3.0, 3.0)
    xmin, ymin, xmax, ymax = load_world(worlds_dir / "office.yaml").bounds()
    assert (xmax - xmin, ymax - ymin) == (20.0, 15.0)


def test_missing_and_invalid_files(tmp_path: Path) -> None:
    with pytest.raises(WorldError, match="cannot read"):
        load_world(tmp_path / "nope.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("segments: [[[0, 0], [1, 1]]\n")
    with pytest.raises(WorldError, match="not valid YAML"):
        load_world(bad)


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


def test_mask_segments_of_one_pixel_by_hand() -> None:
    occ = np.zeros((2, 3), bool)
    occ[0, 2] = True                                  # top row, right column: grid row 1, column 2
    segs = mask_segments(occ, 0.5, (1.0, 0.0, 0.0))
    corners = {tuple(p) for p in np.round(segs.reshape(-1, 2), 12)}
    assert len(segs) == 4 and corners == {(2.0, 0.5), (2.5, 0.5), (2.0, 1.0), (2.5, 1.0)}


def test_mask_segments_with_a_turned_origin() -> None:
    occ = np.ones((1, 2), bool)                       # two pixels side by side: one run each way
    segs = mask_segments(occ, 1.0, (0.0, 0.0, math.pi / 2))
    assert len(segs) == 4
    pts = segs.reshape(-1, 2)
    # the map's x axis points along world +y: the 2 x 1 block covers x in [-1, 0], y in [0, 2]
    np.testing.assert_allclose(pts.min(axis=0), [-1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(pts.max(axis=0), [0.0, 2.0], atol=1e-12)


def test_mask_segments_of_a_hole_keep_inner_edges() -> None:
    occ = np.ones((3, 3), bool)
    occ[1, 1] = False                                 # a ring: outer square and inner square
    segs = mask_segments(occ, 1.0, (0.0, 0.0, 0.0))
    assert len(segs) == 8
    lengths = np.hypot(*(segs[:, 1] - segs[:, 0]).T)
    assert sorted(lengths.tolist()) == [1.0] * 4 + [3.0] * 4


@pytest.mark.parametrize("edit, message", [
    (("resolution: 0.5", "origin: [0, 0, 0]"), "resolution: missing"),
    (("origin: [-1.0, -2.0, 0.0]", "origin: [1, 2]"), "origin: expected [x, y, yaw]"),
    (("occupied_thresh: 0.65", "occupied_thresh: 1.5"), "occupied_thresh=1.5 must be in (0, 1)"),
    (("spawn: [0.25, -1.25, 90]", "spawn: [0, 0]"), "spawn: expected [x, y, yaw_deg]"),
    (("image: m.pgm", "image: gone.pgm"), "image:"),
])
def test_bad_map_fields_are_named(tmp_path: Path, edit: tuple[str, str], message: str) -> None:
    px = np.full((2, 2), 254, np.uint8)
    px[0, 0] = 0
    y = _write_map(tmp_path, px)
    y.write_text(y.read_text().replace(*edit))
    with pytest.raises(WorldError, match=__import__("re").escape(message)):
        load_world(y)


def test_a_map_without_occupied_pixels_is_an_error(tmp_path: Path) -> None:
    with pytest.raises(WorldError, match="no occupied pixel"):
        load_world(_write_map(tmp_path, np.full((2, 2), 254, np.uint8)))


def test_a_bad_world_file_names_the_file(tmp_path: Path) -> None:
    (tmp_path / "w.yaml").write_text("circles: [[0, 0, -1]]\n")
    with pytest.raises(WorldError, match=r"w.yaml: circles\[0\].r"):
        load_world(tmp_path / "w.yaml")
    (tmp_path / "pillar.yaml").write_text("circles: [[1, 1, 0.3]]\n")
    assert load_world(tmp_path / "pillar.yaml").name == "pillar"       # named after the file


def test_pillar_room(pillar_room) -> None:
    assert pillar_room.name == "pillar_room" and pillar_room.bounds() == (-2.5, -2.5, 2.5, 2.5)
    np.testing.assert_allclose(pillar_room.circles, [[1.0, 1.0, 0.3]])
    # from the centre the pillar's surface (sqrt 2 - 0.3) is nearer than the walls (2.5)
    np.testing.assert_allclose(pillar_room.clearance(np.array([[0.0, 0.0], [-2.0, -2.0]])),
                               [math.sqrt(2) - 0.3, 0.5])
