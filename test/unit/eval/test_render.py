"""Map pictures through Pillow: PNG files, pixel-exact maps and paths, and map.png's
crop, scale bar, legend and shrinking of large maps."""
from __future__ import annotations

import math

import numpy as np
from PIL import Image, ImageDraw

from fastslam.eval.render import (
    MAX_SCALE,
    STRIP,
    draw_path,
    explored_box,
    map_picture,
    merge_cells,
    nice_length,
    render_map,
    world_to_pixels,
    write_png,
)

RED = (255, 0, 0)
GREEN = (0, 160, 0)


def test_png_opens_in_pillow_with_the_same_pixels(tmp_path):
    rgb = np.random.default_rng(1).integers(0, 256, size=(17, 31, 3), dtype=np.uint8)
    path = write_png(tmp_path / "a.png", rgb)
    with Image.open(path) as img:
        assert (img.format, img.mode) == ("PNG", "RGB")
        np.testing.assert_array_equal(np.asarray(img), rgb)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png"]   # no temporary left


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


def test_a_point_that_is_not_finite_breaks_the_path():
    img = Image.new("RGB", (5, 5))
    draw_path(ImageDraw.Draw(img), [[0.5, 0.5], [np.nan, np.nan], [4.5, 0.5], [4.5, 4.5]], RED)
    red = np.all(np.asarray(img) == RED, axis=2)
    # a lone pixel at (0, 0), then the segment down column 4; nothing joins them
    assert red[0, 0] and red[:, 4].all() and red.sum() == 6


def _room(size=200, explored=(50, 80, 120, 140)):
    """An unknown grid with a known rectangle rows r0:r1, cols c0:c1 walled by occupied cells."""
    occ = np.full((size, size), -1, np.int8)
    r0, r1, c0, c1 = explored
    occ[r0:r1, c0:c1] = 0
    occ[r0, c0:c1] = occ[r1 - 1, c0:c1] = occ[r0:r1, c0] = occ[r0:r1, c1 - 1] = 100
    return occ


def test_explored_box_with_margin_inside_the_grid():
    occ = _room()
    assert explored_box(occ, 5) == (45, 85, 115, 145)
    assert explored_box(occ, 100) == (0, 180, 20, 200)        # clipped at the grid's edges
    assert explored_box(np.full((4, 6), -1, np.int8), 2) == (0, 4, 0, 6)


def test_map_png_is_cropped_to_the_explored_area_plus_the_margin():
    # 30 x 20 known cells of 0.05 m, margin 0.25 m = 5 cells: 40 x 30 cells, scaled by 8
    path = np.array([[1.325, -1.975], [1.825, -0.975]])     # centres of grid cells (126, 60) and (136, 80)
    pic = map_picture(_room(), 0.05, (-5.0, -5.0, 0.0), {"estimate": (path, RED)}, margin=0.25)
    assert (pic.width, pic.height) == (30 * MAX_SCALE, 40 * MAX_SCALE + STRIP)
    px = np.asarray(pic)
    # the wall of grid row 50 (picture row 40 - 5 - 1 = 34 in cells) is black across the known columns
    assert np.all(px[34 * MAX_SCALE + 3, 5 * MAX_SCALE:25 * MAX_SCALE] == 0)
    # the crop starts at grid cell (115, 45): the path's ends are the centres of cropped cells
    # (11, 15) and (21, 35), picture rows counted from the top (a 2 px line: within 2 px)
    red = np.all(px[:-STRIP] == RED, axis=2)
    for col, row in ((11, 15), (21, 35)):
        y, x = (40 - row) * MAX_SCALE - 4, col * MAX_SCALE + 4
        assert red[y - 2:y + 3, x - 2:x + 3].any()
    rows, cols = np.nonzero(red)
    assert rows.min() >= 5 * MAX_SCALE - 6 and rows.max() <= 25 * MAX_SCALE - 2
    assert cols.min() >= 11 * MAX_SCALE + 1 and cols.max() <= 21 * MAX_SCALE + 6


def test_scale_bar_is_a_round_number_of_metres_long():
    occ = _room()
    pic = map_picture(occ, 0.05, (0.0, 0.0, 0.0), margin=0.25)
    strip = np.asarray(pic)[-STRIP:]
    black = np.all(strip[STRIP // 2] == 0, axis=1)          # the bar's middle row
    start = int(np.argmax(black))
    length = int(np.argmin(black[start:]))
    # 30 cells of 0.05 m at 8 px each: 240 px; a quarter, 0.375 m, rounds down to a 0.2 m bar = 32 px
    assert (start, length) == (10, 32)
    assert nice_length(1.5) == 1.0 and nice_length(0.3) == 0.2 and nice_length(7.0) == 5.0 and nice_length(20) == 20


def test_legend_shows_each_path_colour_in_the_strip():
    paths = {"reference": (np.array([[6.2, 3.0], [6.5, 3.5]]), GREEN), "estimate": (np.array([[6.3, 3.0]]), RED)}
    strip = np.asarray(map_picture(_room(), 0.05, (0.0, 0.0, 0.0), paths))[-STRIP:]
    for colour in (GREEN, RED):
        assert np.all(strip == colour, axis=2).sum() >= 16 * 3   # a 16 x 3 px swatch each


def test_a_large_map_shrinks_without_losing_its_walls():
    occ = _room(size=5000, explored=(0, 5000, 0, 5000))
    occ[2501, :] = 100                                      # a wall one cell thick across the map
    pic = map_picture(occ, 0.05, (0.0, 0.0, 0.0), max_side=2000)
    assert pic.height - STRIP == 1667 and pic.width == 1667  # ceil(5000 / 3) cells of 3 x 3
    px = np.asarray(pic)[:-STRIP, :, 0]
    assert np.all(px[1667 - 1 - 2501 // 3] == 0)             # the wall's merged row stays black
    np.testing.assert_array_equal(merge_cells(np.array([[-1, 0, 100], [-1, -1, 0]], np.int8), 2),
                                  [[0, 100]])


def test_map_picture_of_an_unexplored_grid_is_the_whole_grid():
    pic = map_picture(np.full((10, 20), -1, np.int8), 0.1, (0.0, 0.0, 0.0))
    assert (pic.width, pic.height - STRIP) == (20 * MAX_SCALE, 10 * MAX_SCALE)
