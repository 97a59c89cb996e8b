"""2D worlds of exact primitives for the simulator: segments, circles, polygons.

A world file is a small YAML mapping (all lengths in metres, angles in degrees)::

    name: room
    spawn: [x, y, yaw_deg]
    segments: [[[x1, y1], [x2, y2]], ...]          # thin walls
    circles:  [[cx, cy, r], ...]                     # pillars
    polygons:                                        # closed, solid unless solid: false
      - [[x, y], [x, y], [x, y], ...]
      - {center: [x, y], radius: R, sides: 6, yaw: 0}   # regular polygon, R = circumradius
      - {points: [[x, y], ...], solid: false}         # an enclosure: free inside

A map_server map (YAML with an ``image`` key: PGM, PNG, ...) loads as well: the edges between
occupied and other pixels become segments. Every error is a ``WorldError`` naming the field.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray
    Array = NDArray[np.float64]


class WorldError(ValueError):
    """A world file is missing, malformed or has a bad field."""


@dataclass
class World:
    """Static geometry in the world frame.

    segments: (K, 2, 2) float64, segment k from segments[k, 0] to segments[k, 1] (polygon edges included).
    circles: (C, 3) float64 rows [cx, cy, r].
    polygons: closed polygons (V, 2) each, kept for inside tests; ``solid[i]`` False = enclosure.
    spawn: (3,) float64 [x, y, theta] robot start pose, theta in radians.
    """

    segments: Array = field(default_factory=lambda: np.zeros((0, 2, 2)))
    circles: Array = field(default_factory=lambda: np.zeros((0, 3)))
    polygons: list[Array] = field(default_factory=list)
    solid: list[bool] = field(default_factory=list)
    spawn: Array = field(default_factory=lambda: np.zeros(3))
    name: str = "world"

    def clearance(self, points: Array) -> Array:
        """Distance (P,) from points (P, 2) to the nearest segment or circle boundary; inf if empty."""
        p = np.asarray(points, dtype=float).reshape(-1, 2)
        d = np.full(len(p), np.inf)
        if len(self.segments):
            a, e = self.segments[:, 0], self.segments[:, 1] - self.segments[:, 0]   # (K, 2)
            ee = np.maximum(np.einsum("kj,kj->k", e, e), 1e-18)
            rel = p[:, None, :] - a[None]                                           # (P, K, 2)
            u = np.clip(np.einsum("pkj,kj->pk", rel, e) / ee, 0.0, 1.0)
            d = np.minimum(d, np.hypot(*(rel - u[..., None] * e).transpose(2, 0, 1)).min(axis=1))
        if len(self.circles):
            dc = np.hypot(p[:, None, 0] - self.circles[:, 0], p[:, None, 1] - self.circles[:, 1])
            d = np.minimum(d, np.abs(dc - self.circles[:, 2]).min(axis=1))
        return d

    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of all geometry."""
        pts = [self.segments.reshape(-1, 2)]
        if len(self.circles):
            c, r = self.circles[:, :2], self.circles[:, 2:]
            pts += [c - r, c + r]
        allp = np.concatenate(pts) if sum(len(q) for q in pts) else np.zeros((1, 2))
        return (*allp.min(axis=0), *allp.max(axis=0))

    def sample_boundary(self, spacing: float) -> Array:
        """Points (P, 2) every ``spacing`` m along every segment and circle, world frame.

        Points hidden inside a solid polygon or circle, or outside every enclosure, are
        dropped: no laser can see them, so a ground-truth raster should not contain them.
        """
        if spacing <= 0:
            raise ValueError("spacing must be > 0")
        parts = [np.zeros((0, 2))]
        for a, b in self.segments:
            n = max(int(math.ceil(np.hypot(*(b - a)) / spacing)), 1)
            parts.append(a + np.linspace(0.0, 1.0, n + 1)[:, None] * (b - a))
        for cx, cy, r in self.circles:
            n = max(int(math.ceil(2 * math.pi * r / spacing)), 8)
            t = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
            parts.append(np.stack([cx + r * np.cos(t), cy + r * np.sin(t)], axis=1))
        pts = np.concatenate(parts)
        keep = np.ones(len(pts), bool)
        encl = [p for p, s in zip(self.polygons, self.solid) if not s]
        for poly, s in zip(self.polygons, self.solid):
            if s:
                keep &= ~(inside_polygon(pts, poly) & ~_on_polygon(pts, poly))
        if len(self.circles):
            dc = np.hypot(pts[:, None, 0] - self.circles[:, 0], pts[:, None, 1] - self.circles[:, 1])
            keep &= ~(dc < self.circles[:, 2] - 1e-6).any(axis=1)
        if encl:
            inside_any = np.zeros(len(pts), bool)
            for poly in encl:
                inside_any |= inside_polygon(pts, poly) | _on_polygon(pts, poly)
            keep &= inside_any
        return pts[keep]


def inside_polygon(points: Array, poly: Array) -> NDArray[np.bool_]:
    """Crossing-number test: (P,) True where points (P, 2) lie inside the closed polygon (V, 2)."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    a, b = poly, np.roll(poly, -1, axis=0)                       # edges a[v] -> b[v]
    px, py = p[:, 0, None], p[:, 1, None]
    straddle = (a[:, 1] > py) != (b[:, 1] > py)                  # (P, V)
    with np.errstate(divide="ignore", invalid="ignore"):
        xcross = a[:, 0] + (py - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return (straddle & (px < xcross)).sum(axis=1) % 2 == 1


def _on_polygon(points: Array, poly: Array, tol: float = 1e-6) -> NDArray[np.bool_]:
    return World(segments=polygon_segments(poly)).clearance(points) < tol


def polygon_segments(poly: Array) -> Array:
    """Closed polygon (V, 2) -> its V edges (V, 2, 2)."""
    return np.stack([poly, np.roll(poly, -1, axis=0)], axis=1)


def regular_polygon(center: tuple[float, float], radius: float, sides: int, yaw_deg: float = 0.0) -> Array:
    """Vertices (sides, 2) of a regular polygon; the first vertex at angle yaw from the centre."""
    t = math.radians(yaw_deg) + 2 * math.pi * np.arange(sides) / sides
    return np.stack([center[0] + radius * np.cos(t), center[1] + radius * np.sin(t)], axis=1)


# ----------------------------------------------------------------------------- YAML loading

def _points(value: Any, where: str, n: int | None = None) -> Array:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise WorldError(f"{where}: expected a list of [x, y] numbers, got {value!r}") from None
    if arr.ndim != 2 or arr.shape[1] != 2 or (n is not None and len(arr) != n):
        want = f"{n} points" if n else "a list of [x, y] points"
        raise WorldError(f"{where}: expected {want}, got {value!r}")
    if not np.isfinite(arr).all():
        raise WorldError(f"{where}: coordinates must be finite, got {value!r}")
    return arr


def _number(value: Any, where: str, lo: float = -math.inf, lo_open: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise WorldError(f"{where}: expected a finite number, got {value!r}")
    if value < lo or (lo_open and value == lo):
        raise WorldError(f"{where}={value!r} must be {'>' if lo_open else '>='} {lo}")
    return float(value)


def _polygon(item: Any, where: str) -> tuple[Array, bool]:
    if isinstance(item, dict):
        unknown = sorted(set(item) - {"points", "center", "radius", "sides", "yaw", "solid"})
        if unknown:
            raise WorldError(f"{where}.{unknown[0]}: unknown field")
        solid = item.get("solid", True)
        if not isinstance(solid, bool):
            raise WorldError(f"{where}.solid: expected true or false, got {solid!r}")
        if "points" in item:
            return _polygon(item["points"], f"{where}.points")[0], solid
        if "center" not in item or "radius" not in item:
            raise WorldError(f"{where}: needs 'points' or 'center' and 'radius'")
        c = _points([item["center"]], f"{where}.center", 1)[0]
        r = _number(item["radius"], f"{where}.radius", 0.0, lo_open=True)
        sides = item.get("sides", 6)
        if isinstance(sides, bool) or not isinstance(sides, int) or sides < 3:
            raise WorldError(f"{where}.sides={sides!r} must be an integer >= 3")
        yaw = _number(item.get("yaw", 0.0), f"{where}.yaw")
        return regular_polygon((c[0], c[1]), r, sides, yaw), solid
    pts = _points(item, where)
    if len(pts) < 3:
        raise WorldError(f"{where}: a polygon needs at least 3 points, got {len(pts)}")
    return pts, True


def world_from_dict(data: Any, name: str = "world") -> World:
    """Builds a World from a parsed world YAML mapping; raises WorldError naming the bad field."""
    if not isinstance(data, dict):
        raise WorldError(f"{name}: a world file must be a mapping with segments/circles/polygons/spawn")
    unknown = sorted(set(data) - {"name", "spawn", "segments", "circles", "polygons", "description"})
    if unknown:
        raise WorldError(f"{unknown[0]}: unknown field (allowed: name, spawn, segments, circles, polygons)")
    segs: list[Array] = []
    for i, s in enumerate(data.get("segments") or []):
        segs.append(_points(s, f"segments[{i}]", 2)[None])
    circles = []
    for i, c in enumerate(data.get("circles") or []):
        if not isinstance(c, (list, tuple)) or len(c) != 3:
            raise WorldError(f"circles[{i}]: expected [cx, cy, r], got {c!r}")
        circles.append([_number(c[0], f"circles[{i}].cx"), _number(c[1], f"circles[{i}].cy"),
                        _number(c[2], f"circles[{i}].r", 0.0, lo_open=True)])
    polys, solid = [], []
    for i, p in enumerate(data.get("polygons") or []):
        poly, s = _polygon(p, f"polygons[{i}]")
        polys.append(poly)
        solid.append(s)
        segs.append(polygon_segments(poly))
    spawn = data.get("spawn", [0.0, 0.0, 0.0])
    if not isinstance(spawn, (list, tuple)) or len(spawn) not in (2, 3):
        raise WorldError(f"spawn: expected [x, y, yaw_deg], got {spawn!r}")
    sp = [_number(v, f"spawn[{i}]") for i, v in enumerate(spawn)] + [0.0] * (3 - len(spawn))
    world = World(segments=np.concatenate(segs) if segs else np.zeros((0, 2, 2)),
                  circles=np.asarray(circles, dtype=float).reshape(-1, 3), polygons=polys, solid=solid,
                  spawn=np.array([sp[0], sp[1], math.radians(sp[2])]), name=str(data.get("name", name)))
    if not len(world.segments) and not len(world.circles):
        raise WorldError(f"{name}: the world has no geometry (segments, circles or polygons)")
    xy = world.spawn[None, :2]
    inside_solid = any(inside_polygon(xy, p)[0] for p, s in zip(polys, solid) if s) or bool(
        len(world.circles) and (np.hypot(*(xy[0] - world.circles[:, :2]).T) < world.circles[:, 2]).any())
    if world.clearance(xy)[0] < 1e-3 or inside_solid:
        raise WorldError(f"spawn: {spawn!r} lies on or inside an obstacle")
    return world
