"""Worlds from files: a world YAML (walls as polygons, segments, circles) or a
map_server map (YAML + image: PGM, PNG, ...), whose occupied pixels become walls.

Only the edges between an occupied pixel and a non-occupied one are kept, merged into
runs along rows and columns, so a 384 x 384 map gives hundreds of segments, not
four per pixel.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from fastslam.geometry import transform_points
from fastslam.io.map_files import MapLoadError, read_image, trinary
from fastslam.sim.world import World, WorldError, world_from_dict

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


def mask_segments(occ: NDArray[np.bool_], resolution: float, origin: tuple[float, float, float]) -> NDArray[np.float64]:
    """(K, 2, 2) boundary segments of the occupied cells of ``occ`` (H, W), row 0 = top."""
    h, w = occ.shape
    grid = np.pad(occ[::-1], 1)                       # row 0 = bottom (y up), a free border
    segs: list[tuple[float, float, float, float]] = []
    # horizontal edges at grid line j (between rows j-1 and j of the unpadded grid)
    hedge = grid[1:, 1:-1] != grid[:-1, 1:-1]         # (H+1, W)
    for j in np.flatnonzero(hedge.any(axis=1)):
        runs = np.diff(np.concatenate([[0], hedge[j].astype(np.int8), [0]]))
        for s, e in zip(np.flatnonzero(runs == 1), np.flatnonzero(runs == -1)):
            segs.append((s, j, e, j))
    vedge = grid[1:-1, 1:] != grid[1:-1, :-1]         # (H, W+1)
    for i in np.flatnonzero(vedge.any(axis=0)):
        runs = np.diff(np.concatenate([[0], vedge[:, i].astype(np.int8), [0]]))
        for s, e in zip(np.flatnonzero(runs == 1), np.flatnonzero(runs == -1)):
            segs.append((i, s, i, e))
    cells = np.asarray(segs, dtype=float).reshape(-1, 2, 2) * resolution
    x, y = transform_points(origin, cells.reshape(-1, 2))
    return np.stack([x, y], axis=-1).reshape(-1, 2, 2)


def world_from_map_yaml(data: dict[str, Any], path: Path) -> World:
    """map_server YAML fields (image, resolution, origin, negate, occupied_thresh) -> World.

    An optional non-standard ``spawn: [x, y, yaw_deg]`` sets the start pose (default 0, 0, 0).
    """
    def num(key: str, default: Any = None) -> float:
        v = data.get(key, default)
        if v is None:
            raise WorldError(f"{path.name}: {key}: missing")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise WorldError(f"{path.name}: {key}: expected a number, got {v!r}")
        return float(v)

    res = num("resolution")
    if res <= 0:
        raise WorldError(f"{path.name}: resolution={res} must be > 0")
    origin = data.get("origin", [0.0, 0.0, 0.0])
    if not isinstance(origin, list) or len(origin) != 3 or not all(isinstance(v, (int, float)) for v in origin):
        raise WorldError(f"{path.name}: origin: expected [x, y, yaw], got {origin!r}")
    thresh = num("occupied_thresh", 0.65)
    if not 0.0 < thresh < 1.0:
        raise WorldError(f"{path.name}: occupied_thresh={thresh} must be in (0, 1)")
    image = Path(str(data["image"]))
    if not image.is_absolute():
        image = path.parent / image
    try:
        pixels, white = read_image(image)
    except (MapLoadError, OSError) as err:
        raise WorldError(f"image: {err}") from None
    occ = trinary(pixels, negate=bool(data.get("negate", 0)), occupied_thresh=thresh, maxval=white) == 100
    if not occ.any():
        raise WorldError(f"{path.name}: image {image.name} has no occupied pixel")
    spawn = data.get("spawn", [0.0, 0.0, 0.0])
    if not isinstance(spawn, list) or len(spawn) != 3:
        raise WorldError(f"{path.name}: spawn: expected [x, y, yaw_deg], got {spawn!r}")
    return World(segments=mask_segments(occ, res, (float(origin[0]), float(origin[1]), float(origin[2]))),
                  spawn=np.array([float(spawn[0]), float(spawn[1]), math.radians(float(spawn[2]))]),
                  name=path.stem)


def load_world(path: str | Path) -> World:
    """Reads a world YAML, or a map_server map YAML (it has an ``image`` key)."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except OSError as err:
        raise WorldError(f"cannot read world file {path}: {err.strerror}") from None
    except yaml.YAMLError as err:
        raise WorldError(f"{path}: not valid YAML: {err}") from None
    if isinstance(data, dict) and "image" in data:
        return world_from_map_yaml(data, path)
    try:
        return world_from_dict(data, name=path.stem)
    except WorldError as err:
        raise WorldError(f"{path.name}: {err}") from None
