"""Pictures of maps and trajectories, drawn with Pillow.

``render_map`` draws an OccupancyGrid (row 0 at the BOTTOM of the picture, as seen from
above) scaled up by an integer factor, with trajectories as polylines on top.
``map_picture`` is what the tools save as map.png: the map cropped to its explored part
plus a margin, each cell a few pixels wide (or, past a pixel limit, several cells per
pixel with occupied cells winning, so a large map shrinks instead of being cut), and a
strip under it with a scale bar in metres and the legend of the paths.
"""
from __future__ import annotations

import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Tuple

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from fastslam.geometry import compose, inverse, transform_points
from fastslam.io.staging import staged

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import ArrayLike, NDArray

Colour = Tuple[int, int, int]
Paths = Mapping[str, Tuple["ArrayLike", Colour]]   # name -> ((T, 2) xy [m], (r, g, b)), drawn in order

UNKNOWN_RGB = (205, 205, 205)
FREE_RGB = (255, 255, 255)
OCCUPIED_RGB = (0, 0, 0)
TRUTH_RGB = (0, 160, 0)
ESTIMATE_RGB = (220, 0, 0)
ODOMETRY_RGB = (40, 90, 230)
MAX_SIDE = 2000       # [px] longest side of the map in map_picture; beyond, cells are merged
TARGET_SIDE = 800     # [px] a small map's cells are scaled up towards this size ...
MAX_SCALE = 8         # ... by at most this many pixels per cell
STRIP = 28            # [px] height of the scale bar and legend strip


def write_png(path: str | os.PathLike[str], image: Image.Image | NDArray[np.uint8]) -> Path:
    """Save a picture ((H, W, 3) uint8 RGB, row 0 = top, or a Pillow image) as PNG,
    under a temporary name renamed when complete."""
    path = Path(path)
    img = image if isinstance(image, Image.Image) else Image.fromarray(np.ascontiguousarray(image, np.uint8), "RGB")
    with staged(path) as (tmp,):
        img.save(tmp, format="PNG")
    return path


def map_to_rgb(occupancy: NDArray[np.integer[Any]], scale: int = 1) -> NDArray[np.uint8]:
    """(H, W) OccupancyGrid -> (H*scale, W*scale, 3) RGB, grid row 0 at the bottom.

    Unknown (-1) is grey, 0..100 is shaded linearly from white (free) to black.
    """
    occ = np.asarray(occupancy)
    shade = np.where(occ < 0, UNKNOWN_RGB[0],
                     255 - np.clip(occ.astype(np.int32), 0, 100) * 255 // 100).astype(np.uint8)
    img = np.repeat(shade[::-1, :, None], 3, axis=2)
    if scale > 1:
        img = np.repeat(np.repeat(img, scale, axis=0), scale, axis=1)
    return img


def world_to_pixels(xy: ArrayLike, shape: tuple[int, ...], resolution: float,
                    origin: tuple[float, float, float], scale: int) -> NDArray[np.float64]:
    """(T, 2) map-frame points -> (T, 2) (column, row) coords in a picture of grid ``shape``."""
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    gx, gy = transform_points(inverse(origin), pts)   # into the grid's frame
    gx, gy = gx / resolution, gy / resolution           # [cells]
    return np.stack([gx * scale, (shape[0] - gy) * scale], axis=1)


def draw_path(draw: ImageDraw.ImageDraw, pixels_xy: ArrayLike, colour: Colour, width: int = 1) -> None:
    """A polyline through (T, 2) (column, row) picture coordinates; a point that is not
    finite breaks the line in two."""
    pts = np.asarray(pixels_xy, dtype=np.float64).reshape(-1, 2)
    # pixel (c, r) covers [c, c + 1) x [r, r + 1); the clip keeps far points in C's int range
    cells = np.floor(np.clip(pts, -1e6, 1e6))
    finite = np.all(np.isfinite(pts), axis=1)
    breaks = np.flatnonzero(np.diff(finite.astype(np.int8)) != 0) + 1
    for run in np.split(np.arange(len(pts)), breaks):
        if len(run) == 0 or not finite[run[0]]:
            continue
        xy = [(int(c), int(r)) for c, r in cells[run]]
        if len(xy) == 1:
            draw.point(xy, fill=colour)
        else:
            draw.line(xy, fill=colour, width=width)


def render_map(occupancy: NDArray[np.integer[Any]], resolution: float, origin: tuple[float, float, float],
               paths: Paths | None = None, *, scale: int = 1, width: int = 1) -> NDArray[np.uint8]:
    """Grey map with coloured trajectories.

    Args:
        occupancy: (H, W) int8 OccupancyGrid values, row 0 at ``origin``.
        resolution: cell size [m]; origin: (x, y, yaw) of cell (0, 0)'s corner.
        paths: name -> ((T, 2) xy in the map frame [m], (r, g, b)); drawn in dict order.
        scale: integer up-sampling of each cell, so thin paths stay visible.
        width: line width of the paths [px].

    Returns:
        (H*scale, W*scale, 3) uint8 RGB, row 0 = top of the picture.
    """
    scale = max(1, int(scale))
    img = Image.fromarray(map_to_rgb(occupancy, scale), "RGB")
    draw = ImageDraw.Draw(img)
    shape = np.asarray(occupancy).shape
    for xy, colour in (paths or {}).values():
        draw_path(draw, world_to_pixels(xy, shape, resolution, origin, scale), colour, width)
    return np.asarray(img).copy()


def explored_box(occupancy: NDArray[np.integer[Any]], margin: int) -> tuple[int, int, int, int]:
    """(row0, row1, col0, col1), the rows and columns holding known cells, widened by
    ``margin`` cells and kept inside the grid; the whole grid when nothing is known."""
    known = np.asarray(occupancy) >= 0
    h, w = known.shape
    rows, cols = np.flatnonzero(known.any(axis=1)), np.flatnonzero(known.any(axis=0))
    if len(rows) == 0:
        return 0, h, 0, w
    return (max(rows[0] - margin, 0), min(rows[-1] + 1 + margin, h),
            max(cols[0] - margin, 0), min(cols[-1] + 1 + margin, w))


def merge_cells(occupancy: NDArray[np.integer[Any]], k: int) -> NDArray[np.int8]:
    """Blocks of k x k cells -> one cell holding the block's highest value: occupied
    over free over unknown, so a wall one cell thick survives the shrinking."""
    occ = np.asarray(occupancy, dtype=np.int8)
    h, w = occ.shape
    padded = np.full((-(-h // k) * k, -(-w // k) * k), -1, dtype=np.int8)
    padded[:h, :w] = occ
    return padded.reshape(padded.shape[0] // k, k, padded.shape[1] // k, k).max(axis=(1, 3))


def nice_length(metres: float) -> float:
    """The largest 1, 2 or 5 x 10^k not above ``metres`` (> 0)."""
    power = 10.0 ** math.floor(math.log10(metres))
    return max(m * power for m in (1.0, 2.0, 5.0) if m * power <= metres + 1e-12)


def _text_width(draw: ImageDraw.ImageDraw, text: str, font: Any) -> int:
    if hasattr(draw, "textbbox"):                            # Pillow >= 8
        left, _, right, _ = draw.textbbox((0, 0), text, font=font)
        return int(right - left)
    return int(draw.textsize(text, font=font)[0])  # type: ignore[attr-defined]  # Pillow 7 (Ubuntu 20.04)


def map_picture(occupancy: NDArray[np.integer[Any]], resolution: float, origin: tuple[float, float, float],
                paths: Paths | None = None, *, margin: float = 1.0, max_side: int = MAX_SIDE) -> Image.Image:
    """The map as the tools save it (map.png): cropped to the known cells plus ``margin``
    [m], scaled so that a cell is visible, or shrunk past ``max_side`` pixels; under it a
    white strip with a scale bar in metres and the paths' legend.

    Args: as :func:`render_map`; paths are also drawn where they leave the known area.
    """
    occ = np.asarray(occupancy)
    r0, r1, c0, c1 = explored_box(occ, int(math.ceil(margin / resolution)))
    occ = occ[r0:r1, c0:c1]
    origin = tuple(compose(np.asarray(origin, dtype=np.float64), np.array([c0 * resolution, r0 * resolution, 0.0])))
    cells = max(occ.shape)
    if cells > max_side:
        k = -(-cells // max_side)
        occ, resolution, scale = merge_cells(occ, k), resolution * k, 1
    else:
        scale = int(min(MAX_SCALE, max(1, TARGET_SIDE // cells)))
    rgb = render_map(occ, resolution, (origin[0], origin[1], origin[2]), paths, scale=scale,
                     width=2 if scale >= 3 or occ.shape[1] * scale >= 600 else 1)
    return _with_strip(rgb, resolution / scale, paths or {})


def _with_strip(rgb: NDArray[np.uint8], metres_per_pixel: float, paths: Paths) -> Image.Image:
    font = ImageFont.load_default()
    probe = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    h, w = rgb.shape[:2]
    bar_m = nice_length(max(w / 4, 1) * metres_per_pixel)
    bar_px = max(1, int(round(bar_m / metres_per_pixel)))
    label = f"{bar_m:g} m"
    legend = [(name, colour, _text_width(probe, name, font)) for name, (_, colour) in paths.items()]
    needed = 10 + bar_px + 6 + _text_width(probe, label, font) + sum(40 + tw for _, _, tw in legend) + 10
    canvas = Image.new("RGB", (max(w, needed), h + STRIP), FREE_RGB)
    canvas.paste(Image.fromarray(rgb, "RGB"), (0, 0))
    draw = ImageDraw.Draw(canvas)
    y = h + STRIP // 2
    draw.rectangle((10, y - 1, 10 + bar_px - 1, y + 1), fill=OCCUPIED_RGB)       # the bar, 3 px thick
    draw.rectangle((10, y - 5, 10, y + 5), fill=OCCUPIED_RGB)                    # its end ticks
    draw.rectangle((10 + bar_px - 1, y - 5, 10 + bar_px - 1, y + 5), fill=OCCUPIED_RGB)
    x = 10 + bar_px + 6
    draw.text((x, y - 6), label, fill=OCCUPIED_RGB, font=font)
    x += _text_width(probe, label, font) + 20
    for name, colour, tw in legend:
        draw.rectangle((x, y - 1, x + 15, y + 1), fill=colour)
        draw.text((x + 20, y - 6), name, fill=OCCUPIED_RGB, font=font)
        x += 40 + tw
    return canvas
