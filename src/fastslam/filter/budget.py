"""The filter's bounds: how large its maps may grow, and how much memory they may take.

The maps are the filter's memory (particles x cells, one byte a cell). Their budget is
the memory limit less a reserve for the interpreter, ROS, messages and one scan's work
arrays (particles x beams). The filter refuses a growth that would pass the budget or
max_map_extent and maps on inside; a configuration whose first maps do not fit is an
error at start-up (`startup_problem`).
"""
from __future__ import annotations

import math
import os
import resource
from dataclasses import dataclass
from pathlib import Path

from fastslam.config import SlamConfig
from fastslam.filter.grid import GridMaps

MAX_MAP_EXTENT = 2000.0   # [m] default largest side of the grid (the largest map_width)
MAX_BEAMS = 4096          # default beams per scan the filter takes (more are subsampled)
AUTO_SHARE = 0.8          # memory_limit_mb 0: this share of the machine's (or cgroup's, or ulimit's) memory
RESERVE_MB = 128          # interpreter, numpy, rospy, message buffers: measured 60-90 MB for the node
# Per particle and beam, one scan's arrays (ray slopes and steps, expected ranges,
# weights, the matcher's end points); the traced cells are processed in bounded chunks.
WORK_BYTES_PER_BEAM = 96


def system_memory_bytes() -> int | None:
    """The least of the physical memory, the cgroup's limit and the address-space and
    data ulimits [bytes]; None if none can be read."""
    found: list[int] = []
    try:
        found.append(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        pass
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            text = Path(path).read_text().strip()
        except OSError:
            continue
        if text.isdigit() and int(text) < 2**60:   # v1 writes a huge number for "no limit"
            found.append(int(text))
    for which in (resource.RLIMIT_AS, resource.RLIMIT_DATA):
        soft, _ = resource.getrlimit(which)
        if soft != resource.RLIM_INFINITY and soft > 0:
            found.append(int(soft))
    return min(found) if found else None


def limit_bytes(memory_limit_mb: float) -> int | None:
    """The memory limit [bytes]: memory_limit_mb, or for 0 AUTO_SHARE of the system's."""
    if memory_limit_mb > 0:
        return int(memory_limit_mb * 2**20)
    system = system_memory_bytes()
    return None if system is None else int(AUTO_SHARE * system)


def reserve_bytes(particles: int, beams: int) -> int:
    """Memory besides the maps: the interpreter and one scan's work arrays [bytes]."""
    return RESERVE_MB * 2**20 + particles * beams * WORK_BYTES_PER_BEAM


@dataclass(frozen=True)
class Limits:
    """What the filter's maps may reach: the largest side [m] and bytes (None: no bound)."""

    max_map_extent: float = MAX_MAP_EXTENT
    map_bytes: int | None = None

    @classmethod
    def for_memory(cls, memory_limit_mb: float, particles: int, beams: int = MAX_BEAMS,
                   max_map_extent: float = MAX_MAP_EXTENT) -> Limits:
        """The maps' share of a memory limit (memory_limit_mb 0: the system's, see limit_bytes)."""
        total = limit_bytes(memory_limit_mb)
        maps = None if total is None else max(total - reserve_bytes(particles, beams), 0)
        return cls(max_map_extent=max_map_extent, map_bytes=maps)

    def growth_problem(self, grid: GridMaps, box: tuple[float, float, float, float], fraction: float) -> str | None:
        """Why growing grid to box (xmin, ymin, xmax, ymax) is refused, or None."""
        h, w = grid.grown_shape(*box, fraction=fraction)
        r = grid.resolution
        if max(h, w) * r > self.max_map_extent:
            return (f"the map would grow to {w * r:.0f} x {h * r:.0f} m, beyond max_map_extent "
                    f"{self.max_map_extent:g} m")
        if self.map_bytes is not None:
            need = grid.nbytes + grid.growth_bytes(*box, fraction=fraction)
            if need > self.map_bytes:
                return (f"growing the maps to {w} x {h} cells would take {_mb(need)} MB, more than the "
                        f"memory limit leaves them ({_mb(self.map_bytes)} MB; memory_limit_mb)")
        return None


def startup_problem(cfg: SlamConfig, limits: Limits, limit: str = "memory_limit_mb") -> str | None:
    """Why the configuration cannot start within the limits, or None: one line naming the
    parameters to change (limit: what sets the memory limit, to name it)."""
    h, w = cfg.grid_shape
    side = max(cfg.map_width, cfg.map_height)
    if side > limits.max_map_extent:
        return f"max_map_extent={limits.max_map_extent:g} must be at least map_width/map_height ({side:g} m)"
    need = GridMaps.bytes_for(cfg.particles, (h, w))
    if limits.map_bytes is not None and need > limits.map_bytes:
        larger = "a larger memory_limit_mb" if limit == "memory_limit_mb" else "more memory"
        return (f"{limit}: particles={cfg.particles} maps of {cfg.map_width:g} x {cfg.map_height:g} m at "
                f"map_resolution={cfg.map_resolution:g} m ({w} x {h} cells) need {math.ceil(need / 2**20)} MB, "
                f"more than the limit leaves for maps ({_mb(limits.map_bytes)} MB): use fewer particles, "
                f"a smaller map_width/map_height, a coarser map_resolution or {larger}")
    return None


def _mb(n: int) -> str:
    mb = n / 2**20
    return f"{mb:.1f}" if mb < 10 else f"{mb:.0f}"
