"""A dependency-free PNG writer (zlib + struct) and a map + trajectories renderer.

The renderer draws an OccupancyGrid (row 0 at the BOTTOM of the picture, as seen
from above) scaled up by an integer factor, then trajectories as 1-pixel polylines.
Lines are rasterised by sampling every segment at sub-pixel steps, all segments of a
path at once, so there is no Python loop over pixels or segments.
"""
from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fastslam.geometry import inverse, transform_points

UNKNOWN_RGB = (205, 205, 205)
FREE_RGB = (255, 255, 255)
OCCUPIED_RGB = (0, 0, 0)


def _chunk(kind: bytes, data: bytes) -> bytes:
    body = kind + data
    return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)


def encode_png(rgb: NDArray[np.uint8]) -> bytes:
    """(H, W, 3) uint8 RGB -> PNG file bytes (8-bit truecolour, filter 0 on every row)."""
    img = np.ascontiguousarray(rgb, dtype=np.uint8)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"rgb must be (H, W, 3), got shape {img.shape}")
    h, w, _ = img.shape
    # each scanline starts with its filter-type byte (0 = None)
    raw = np.concatenate([np.zeros((h, 1), dtype=np.uint8), img.reshape(h, w * 3)], axis=1)
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)  # 8 bit, colour type 2 = RGB
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr)
            + _chunk(b"IDAT", zlib.compress(raw.tobytes(), 6)) + _chunk(b"IEND", b""))


def write_png(path: str | os.PathLike[str], rgb: NDArray[np.uint8]) -> Path:
    """Write (H, W, 3) uint8 RGB, row 0 = top of the picture, as a PNG file."""
    path = Path(path)
    path.write_bytes(encode_png(rgb))
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


def draw_polyline(img: NDArray[np.uint8], pixels_xy: ArrayLike, color: tuple[int, int, int]) -> None:
    """Draw a polyline in place; ``pixels_xy`` (T, 2) float are (column, row) image coords.

    Every segment is sampled at half-pixel steps (one batch for all segments), so
    consecutive samples never skip a pixel; samples outside the picture are dropped.
    """
    pts = np.asarray(pixels_xy, dtype=np.float64).reshape(-1, 2)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) == 0:
        return
    if len(pts) == 1:
        samples = pts
    else:
        a, b = pts[:-1], pts[1:]
        # n_i samples per segment (half-pixel spacing), laid out flat: memory grows
        # with the drawn length, not with (segments x longest segment)
        n = np.ceil(2.0 * np.max(np.abs(b - a), axis=1)).astype(np.int64) + 1
        seg = np.repeat(np.arange(len(a)), n)
        first = np.cumsum(n) - n
        t = (np.arange(len(seg)) - first[seg]) / n[seg]
        samples = np.concatenate([a[seg] + t[:, None] * (b - a)[seg], pts[-1:]])
    cols = np.floor(samples[:, 0]).astype(np.int64)
    rows = np.floor(samples[:, 1]).astype(np.int64)
    h, w = img.shape[:2]
    inside = (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h)
    img[rows[inside], cols[inside]] = color


def world_to_pixels(xy: ArrayLike, shape: tuple[int, ...], resolution: float,
                    origin: tuple[float, float, float], scale: int) -> NDArray[np.float64]:
    """(T, 2) map-frame points -> (T, 2) (column, row) coords in a picture of grid ``shape``."""
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    gx, gy = transform_points(inverse(origin), pts)   # into the grid's frame
    gx, gy = gx / resolution, gy / resolution           # [cells]
    return np.stack([gx * scale, (shape[0] - gy) * scale], axis=1)


def render_map(occupancy: NDArray[np.integer[Any]], resolution: float, origin: tuple[float, float, float],
               paths: dict[str, tuple[ArrayLike, tuple[int, int, int]]] | None = None, *,
               scale: int = 1) -> NDArray[np.uint8]:
    """Grey map with coloured trajectories.

    Args:
        occupancy: (H, W) int8 OccupancyGrid values, row 0 at ``origin``.
        resolution: cell size [m]; origin: (x, y, yaw) of cell (0, 0)'s corner.
        paths: name -> ((T, 2) xy in the map frame [m], (r, g, b)); drawn in dict order.
        scale: integer up-sampling of each cell, so thin paths stay visible.

    Returns:
        (H*scale, W*scale, 3) uint8 RGB, row 0 = top of the picture.
    """
    scale = max(1, int(scale))
    img = map_to_rgb(occupancy, scale)
    for xy, color in (paths or {}).values():
        draw_polyline(img, world_to_pixels(xy, np.asarray(occupancy).shape,
                                           resolution, origin, scale), color)
    return img
