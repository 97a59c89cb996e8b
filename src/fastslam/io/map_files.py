"""map_server map files: a binary P5 PGM plus a YAML description, written atomically.
Images go through Pillow: any image map_server's loader takes (PGM of any maxval, PNG,
...) reads, and the PGM written is Pillow's.

Pixel convention (map_saver's defaults, trinary mode): free cells (0..25) are 254,
occupied cells (>= 65) are 0, everything else (unknown -1 and the uncertain middle)
is 205. The image's first row is the grid's LAST row (OccupancyGrid row 0 is at the
bottom, at ``origin``), so the PGM looks like the map seen from above.
"""
from __future__ import annotations

import io
import os
import re
import tempfile
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml
from PIL import Image, PpmImagePlugin

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


FREE_PIXEL = 254
OCCUPIED_PIXEL = 0
UNKNOWN_PIXEL = 205
FREE_MAX = 25         # [%] map_saver writes 254 for 0 <= v <= 25
OCCUPIED_MIN = 65     # [%] and 0 for v >= 65
OCCUPIED_THRESH = 0.65  # map_server's reading rule: occupied above, free below FREE_THRESH
FREE_THRESH = 0.196


class MapSaveError(OSError):
    """A map could not be written; any earlier files of the same name are untouched."""


class MapLoadError(ValueError):
    """A map YAML or its image is missing or malformed."""


def _paths(path_stem_or_yaml: str | os.PathLike[str]) -> tuple[Path, Path]:
    p = Path(path_stem_or_yaml)
    stem = p.with_suffix("") if p.suffix in (".yaml", ".yml", ".pgm") else p
    return stem.with_name(stem.name + ".pgm"), stem.with_name(stem.name + ".yaml")


def occupancy_to_pixels(occupancy: NDArray[np.integer[Any]]) -> NDArray[np.uint8]:
    """(H, W) OccupancyGrid values -> (H, W) uint8 PGM pixels, image row 0 = grid row H-1."""
    occ = np.asarray(occupancy)
    pixels = np.full(occ.shape, UNKNOWN_PIXEL, dtype=np.uint8)
    pixels[(occ >= 0) & (occ <= FREE_MAX)] = FREE_PIXEL
    pixels[occ >= OCCUPIED_MIN] = OCCUPIED_PIXEL
    return pixels[::-1].copy()


def _stage(path: Path, data: bytes) -> str:
    """Write ``data`` to a fsync'ed temp file next to ``path``; return its name."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)          # mkstemp creates 0600; map files are meant to be shared
    except BaseException:
        _discard(tmp)
        raise
    return tmp


def _discard(tmp: str) -> None:
    try:
        os.unlink(tmp)
    except OSError:
        pass


def _atomic_write_all(files: list[tuple[Path, bytes]]) -> None:
    """Stage every file first, then rename them into place: readers never see a
    half-written file, and a failure while staging (read-only folder, full disk)
    leaves all previous files untouched."""
    staged: list[tuple[str, Path]] = []
    current = files[0][0]
    try:
        for current, data in files:
            staged.append((_stage(current, data), current))
        while staged:
            tmp, current = staged[0]
            os.replace(tmp, current)
            staged.pop(0)
    except OSError as err:
        raise MapSaveError(f"cannot write map file {current}: {err.strerror or err}") from err
    finally:
        for tmp, _ in staged:
            _discard(tmp)


def save_map(path_stem_or_yaml: str | os.PathLike[str], occupancy: NDArray[np.integer[Any]],
             resolution: float, origin: tuple[float, float, float], *,
             occupied_thresh: float = OCCUPIED_THRESH, free_thresh: float = FREE_THRESH,
             versioned: bool = False) -> tuple[Path, Path]:
    """Write ``<stem>.pgm`` and ``<stem>.yaml`` in map_server format, the YAML last.

    Args:
        path_stem_or_yaml: ``maps/intel`` or ``maps/intel.yaml`` (``.pgm`` also accepted).
        occupancy: (H, W) int8, ROS OccupancyGrid values (-1 unknown, 0..100), row 0 at ``origin``.
        resolution: cell size [m].
        origin: (x, y, yaw) of cell (0, 0)'s lower-left corner in the map frame [m, m, rad].
        occupied_thresh, free_thresh: written to the YAML for map_server's reading rule.
        versioned: the image gets a new unique name (``<stem>.saved-<random>.pgm``) and the
            previous one is removed once the YAML points to the new one: a save killed
            at any moment leaves a YAML and the image it names (saves that overwrite
            a map in use, as the node's do). ``<stem>.pgm`` is then made the same file
            (a hard link; a copy where links fail), for whoever opens the image by name.

    Returns:
        (pgm_path, yaml_path).

    Raises:
        MapSaveError: the folder is missing or read-only, the disk is full, ...
    """
    occ = np.asarray(occupancy)
    if occ.ndim != 2:
        raise ValueError(f"occupancy must be (H, W), got shape {occ.shape}")
    pgm_path, yaml_path = _paths(path_stem_or_yaml)
    if versioned:
        with _SAVE_LOCK:  # one versioned save at a time: each removes the image before it
            return _save_versioned(yaml_path, occ, resolution, origin, occupied_thresh, free_thresh)
    meta = _meta(pgm_path.name, resolution, origin, occupied_thresh, free_thresh)
    _atomic_write_all([(pgm_path, _pgm_bytes(occ)), (yaml_path, _yaml_bytes(meta))])
    return pgm_path, yaml_path


_SAVE_LOCK = threading.Lock()
VERSIONED = ".saved-"  # versioned images: <stem>.saved-<random>.pgm


def _pgm_bytes(occ: NDArray[np.integer[Any]]) -> bytes:
    """A binary P5 PGM, maxval 255, as map_saver writes."""
    buf = io.BytesIO()
    Image.fromarray(occupancy_to_pixels(occ), mode="L").save(buf, format="PPM")
    return buf.getvalue()


def _yaml_bytes(meta: dict[str, Any]) -> bytes:
    return yaml.safe_dump(meta, sort_keys=False).encode("utf-8")


def _meta(image: str, resolution: float, origin: tuple[float, float, float], occupied_thresh: float,
          free_thresh: float) -> dict[str, Any]:
    return {"image": image,             # relative, so the pair can be moved together
            "resolution": float(resolution),
            "origin": [float(origin[0]), float(origin[1]), float(origin[2])],
            "negate": 0, "occupied_thresh": float(occupied_thresh), "free_thresh": float(free_thresh),
            "mode": "trinary"}


def _image_of(yaml_path: Path) -> Path | None:
    """The image an existing map YAML names, or None."""
    try:
        image = yaml.safe_load(yaml_path.read_text()).get("image")
    except (OSError, AttributeError, yaml.YAMLError):
        return None
    return yaml_path.parent / str(image) if image else None


def _save_versioned(yaml_path: Path, occ: NDArray[np.integer[Any]], resolution: float,
                    origin: tuple[float, float, float], occupied_thresh: float, free_thresh: float
                    ) -> tuple[Path, Path]:
    stem = yaml_path.name[:-len(yaml_path.suffix)]
    before = _image_of(yaml_path)
    try:
        fd, name = tempfile.mkstemp(prefix=f"{stem}{VERSIONED}", suffix=".pgm", dir=yaml_path.parent)
        os.close(fd)
    except OSError as err:
        raise MapSaveError(f"cannot write map file in {yaml_path.parent}: {err.strerror or err}") from err
    pgm_path = Path(name)
    try:
        _atomic_write_all([(pgm_path, _pgm_bytes(occ))])
        meta = _meta(pgm_path.name, resolution, origin, occupied_thresh, free_thresh)
        _atomic_write_all([(yaml_path, _yaml_bytes(meta))])   # the moment the new map is the map
    except BaseException:
        _discard(str(pgm_path))
        raise
    if before is not None and before != pgm_path and before.name.startswith(f"{stem}{VERSIONED}"):
        _discard(str(before))
    _same_file(pgm_path, yaml_path.with_name(f"{stem}.pgm"))
    return pgm_path, yaml_path


def _same_file(image: Path, plain: Path) -> None:
    """Makes plain (<stem>.pgm) the same image as the versioned one, replacing it at once."""
    tmp = plain.with_name(f".{plain.name}.{os.urandom(4).hex()}.tmp")
    try:
        os.link(image, tmp)
        os.replace(tmp, plain)
    except OSError:   # a file system without hard links: a copy, staged and renamed
        _discard(str(tmp))
        _atomic_write_all([(plain, image.read_bytes())])


def remove_stale(path_stem_or_yaml: str | os.PathLike[str]) -> list[Path]:
    """Removes what killed saves of this map left: temporary files (its own and those of
    the saves before a reset, ``<stem>-<date>``) and versioned images its YAML does not
    name. Returns what was removed."""
    pgm_path, yaml_path = _paths(path_stem_or_yaml)
    stem = yaml_path.name[:-len(yaml_path.suffix)]
    keep = _image_of(yaml_path)
    folder = yaml_path.parent
    stale = list(folder.glob(f".{stem}.*.tmp")) + list(folder.glob(f".{stem}-[0-9]*.tmp"))  # and reset saves'
    stale += [p for p in folder.glob(f"{stem}{VERSIONED}*.pgm") if p != keep]
    for p in stale:
        _discard(str(p))
    return stale


# Pillow 9.2+ scales PGM pixels of any maxval to 0..255 (0..65535 above 255); Pillow 7
# (Ubuntu 20.04) gives them raw, so the maxval is then read from the header.
_PGM_SCALED = hasattr(PpmImagePlugin, "PpmDecoder")
_PNM_MAXVAL = re.compile(rb"P[25](?:\s|#[^\n]*\n)+\d+(?:\s|#[^\n]*\n)+\d+(?:\s|#[^\n]*\n)+(\d+)")


def read_image(path: str | os.PathLike[str]) -> tuple[NDArray[np.float64], int]:
    """Any image map_server loads (PGM of any maxval, PNG, BMP, ...) as map_server sees it.

    Returns:
        ((H, W) float64 values, the mean of the colour channels without alpha, row 0 =
        top row of the image; the value of white: 255, or 65535 for 16-bit images).

    Raises:
        MapLoadError: missing, unreadable or unknown image.
    """
    try:
        with Image.open(Path(path)) as img:
            img.load()
            if img.mode in ("1", "P", "PA", "CMYK", "YCbCr", "LAB", "HSV"):
                img = img.convert("RGBA" if img.mode in ("P", "PA") else "RGB")
            values = np.asarray(img, dtype=np.float64)
            white = 255 if img.mode in ("L", "LA", "RGB", "RGBA", "RGBX") else 65535
            if img.format == "PPM" and not _PGM_SCALED:
                head = Path(path).read_bytes()[:1024]
                found = _PNM_MAXVAL.match(head)
                white = int(found.group(1)) if found else white
    except (OSError, ValueError, SyntaxError) as err:
        raise MapLoadError(f"cannot read image {path}: {err}") from err
    if values.ndim == 3:   # colour: map_server averages the channels, alpha left out
        colours = values.shape[2] - 1 if values.shape[2] in (2, 4) else values.shape[2]
        values = values[:, :, :colours].mean(axis=2)
    return values, white


def load_map(yaml_path: str | os.PathLike[str]) -> tuple[NDArray[np.int8], float, tuple[float, float, float]]:
    """Read a map_server YAML + image with the trinary rule.

    p = (white - v) / white (or v / white with ``negate``); p > occupied_thresh -> 100,
    p < free_thresh -> 0, else -1.

    Returns:
        (occupancy (H, W) int8 with row 0 at the origin, resolution [m], origin (x, y, yaw)).
    """
    yaml_path = Path(yaml_path)
    try:
        meta = yaml.safe_load(yaml_path.read_text())
        image = yaml_path.parent / str(meta["image"])
        resolution = float(meta["resolution"])
        ox, oy, oyaw = (float(v) for v in meta["origin"])
        occ_t = float(meta.get("occupied_thresh", OCCUPIED_THRESH))
        free_t = float(meta.get("free_thresh", FREE_THRESH))
        negate = bool(int(meta.get("negate", 0)))
        pixels, white = read_image(image)
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError) as err:
        raise MapLoadError(f"cannot load map {yaml_path}: {err}") from err
    occ = trinary(pixels, negate=negate, occupied_thresh=occ_t, free_thresh=free_t, maxval=white)
    return occ[::-1].copy(), resolution, (ox, oy, oyaw)


def trinary(pixels: NDArray[np.floating[Any]] | NDArray[np.integer[Any]], *, negate: bool,
            occupied_thresh: float = OCCUPIED_THRESH, free_thresh: float = FREE_THRESH,
            maxval: int = 255) -> NDArray[np.int8]:
    """map_server's trinary rule, pixel by pixel: p = (maxval - v) / maxval (v / maxval with
    negate); p > occupied_thresh -> 100, p < free_thresh -> 0, else -1 (unknown). ``maxval``
    is the value of white (see :func:`read_image`)."""
    v = pixels.astype(np.float64)
    p = v / maxval if negate else (maxval - v) / maxval
    occ = np.full(pixels.shape, -1, dtype=np.int8)
    occ[p > occupied_thresh] = 100
    occ[p < free_thresh] = 0
    return occ
