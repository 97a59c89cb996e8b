"""PNG writer (decoded here with zlib) and the map + trajectory renderer."""
from __future__ import annotations

import math
import struct
import zlib

import numpy as np
import pytest

from fastslam.eval.render import draw_polyline, encode_png, render_map, world_to_pixels, write_png

RED = (255, 0, 0)


def decode_png(data: bytes) -> np.ndarray:
    """Minimal decoder for our own output: 8-bit RGB, filter 0, one or more IDAT chunks."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, chunks = 8, {}
    idat = b""
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        assert crc == zlib.crc32(kind + body) & 0xFFFFFFFF, kind
        chunks[kind] = body
        idat += body if kind == b"IDAT" else b""
        pos += 12 + length
    assert list(chunks)[-1] == b"IEND"
    w, h, depth, colour, _, _, _ = struct.unpack(">IIBBBBB", chunks[b"IHDR"])
    assert (depth, colour) == (8, 2)
    raw = np.frombuffer(zlib.decompress(idat), dtype=np.uint8).reshape(h, 1 + 3 * w)
    assert np.all(raw[:, 0] == 0)       # filter type None on every row
    return raw[:, 1:].reshape(h, w, 3)


def test_png_decodes_to_the_same_pixels(tmp_path):
    rgb = np.array([[[255, 0, 0], [0, 255, 0], [0, 0, 255]],
                    [[1, 2, 3], [250, 251, 252], [0, 0, 0]]], dtype=np.uint8)
    path = write_png(tmp_path / "a.png", rgb)
    np.testing.assert_array_equal(decode_png(path.read_bytes()), rgb)


def test_png_random_image_round_trip():
    rgb = np.random.default_rng(1).integers(0, 256, size=(17, 31, 3), dtype=np.uint8)
    np.testing.assert_array_equal(decode_png(encode_png(rgb)), rgb)


def test_png_rejects_grey_arrays():
    with pytest.raises(ValueError, match="H, W, 3"):
        encode_png(np.zeros((4, 4), np.uint8))


def test_map_colours_and_bottom_row_first():
    occ = np.array([[0, 100], [-1, 50]], dtype=np.int8)   # grid row 0 = [0, 100]
    img = render_map(occ, 1.0, (0.0, 0.0, 0.0))
    # picture row 0 is grid row 1: unknown grey, 50 -> 255 - 127 = 128
    np.testing.assert_array_equal(img[..., 0], [[205, 128], [255, 0]])
    assert np.all(img[..., 0] == img[..., 1]) and np.all(img[..., 1] == img[..., 2])


def test_horizontal_path_lands_on_the_bottom_row():
    occ = np.zeros((10, 10), np.int8)
    img = render_map(occ, 1.0, (0.0, 0.0, 0.0), {"truth": (np.array([[0.5, 0.5], [9.5, 0.5]]), RED)})
    red = np.all(img == RED, axis=2)
    assert red[9].all() and red.sum() == 10


def test_diagonal_path_is_eight_connected_without_gaps():
    occ = np.zeros((10, 10), np.int8)
    img = render_map(occ, 1.0, (0.0, 0.0, 0.0), {"p": (np.array([[0.5, 0.5], [9.5, 9.5]]), RED)})
    rows, cols = np.nonzero(np.all(img == RED, axis=2))
    # exactly the anti-diagonal of the picture: cell (i, i) of the grid is picture (9 - i, i)
    assert sorted(zip(rows.tolist(), cols.tolist())) == sorted((9 - i, i) for i in range(10))


def test_scale_origin_and_clipping():
    occ = np.zeros((5, 5), np.int8)
    # origin shifted to (-1, -1): world (0, 0) is grid cell (1, 1); scale 2 -> picture rows 6..7
    img = render_map(occ, 1.0, (-1.0, -1.0, 0.0), {"p": (np.array([[0.1, 0.1], [0.9, 0.1], [50.0, 0.1]]), RED)},
                     scale=2)
    red = np.all(img == RED, axis=2)
    assert img.shape == (10, 10, 3)
    assert red[7, 2:].all() and red.sum() == 8      # row 7 from column 2 to the edge, rest clipped


def test_world_to_pixels_with_rotated_origin():
    # origin yaw pi/2: the grid's x axis points along world +y
    px = world_to_pixels([[1.0, 3.0]], (4, 4), 1.0, (1.0, 2.0, math.pi / 2), 1)
    np.testing.assert_allclose(px, [[1.0, 4.0]], atol=1e-12)   # grid (gx=1, gy=0) -> column 1, row 4 - 0


def test_draw_polyline_skips_nan_points():
    img = np.zeros((3, 3, 3), np.uint8)
    draw_polyline(img, [[0.5, 0.5], [np.nan, np.nan]], RED)
    assert np.all(img == RED, axis=2).sum() == 1
