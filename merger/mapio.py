"""ROS map_server files (PGM/PNG image + YAML) and colour overlay PNGs.

Reading follows map_server: ``p = (255 − pixel)/255`` (``pixel/255`` with ``negate: 1``); in
``trinary`` and ``scale`` modes a cell is occupied when ``p > occupied_thresh``, free when
``p < free_thresh``, unknown otherwise; in ``raw`` mode the pixel value is the occupancy value
itself (0..100, anything else unknown). The image's top row is the max-y row (flipped into the ROS
grid order). Writing follows map_saver: P5 PGM with free 254, occupied 0, unknown 205.

Every problem with a file raises :class:`MapFileError` naming the file and the key.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import yaml

from .grid import FREE_S, OCCUPIED_S, UNKNOWN_S, OccupancyGrid, states_from_ros
from .overlay import overlay_rgb

PGM_FREE, PGM_OCCUPIED, PGM_UNKNOWN = 254, 0, 205
MODES = ("trinary", "scale", "raw")


class MapFileError(ValueError):
    """A map file that cannot be read as a ROS map_server map (message: ``file: problem``)."""


def _number(meta: dict, key: str, path: Path, default=None, *, lo=None, hi=None) -> float:
    if key not in meta:
        if default is None:
            raise MapFileError(f"{path}: missing key '{key}'")
        return default
    v = meta[key]
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise MapFileError(f"{path}: key '{key}': expected a number, got {v!r}")
    if (lo is not None and v <= lo) or (hi is not None and v > hi):
        raise MapFileError(f"{path}: key '{key}': expected a number in ({lo}, {hi}], got {v!r}")
    return float(v)


def read_metadata(path) -> dict:
    """Parse and validate a map_server YAML file; returns its keys with defaults filled in."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as e:
        raise MapFileError(f"{path}: cannot read: {e.strerror or e}") from None
    try:
        meta = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise MapFileError(f"{path}: not valid YAML: {str(e).splitlines()[0]}") from None
    if not isinstance(meta, dict):
        raise MapFileError(f"{path}: expected a YAML mapping with keys image, resolution, origin")
    if not isinstance(meta.get("image"), str) or not meta["image"]:
        raise MapFileError(f"{path}: key 'image': expected the image file name, got {meta.get('image')!r}")
    origin = meta.get("origin")
    if (not isinstance(origin, list) or len(origin) not in (2, 3)
            or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in origin)):
        raise MapFileError(f"{path}: key 'origin': expected [x, y, yaw], got {origin!r}")
    if len(origin) == 3 and abs(origin[2]) > 1e-9:
        raise MapFileError(f"{path}: key 'origin': a rotated origin (yaw {origin[2]}) is not supported")
    mode = meta.get("mode", "trinary")
    if mode not in MODES:
        raise MapFileError(f"{path}: key 'mode': expected one of {', '.join(MODES)}, got {mode!r}")
    negate = meta.get("negate", 0)
    if negate not in (0, 1, True, False):
        raise MapFileError(f"{path}: key 'negate': expected 0 or 1, got {negate!r}")
    out = {
        "image": meta["image"],
        "resolution": _number(meta, "resolution", path, lo=0.0, hi=1e3),
        "origin": [float(origin[0]), float(origin[1]), 0.0],
        "negate": int(negate),
        "occupied_thresh": _number(meta, "occupied_thresh", path, 0.65, lo=0.0, hi=1.0),
        "free_thresh": _number(meta, "free_thresh", path, 0.196, lo=-1e-12, hi=1.0),
        "mode": mode,
    }
    if out["free_thresh"] >= out["occupied_thresh"]:
        raise MapFileError(f"{path}: key 'free_thresh': expected < occupied_thresh "
                           f"({out['occupied_thresh']}), got {out['free_thresh']}")
    return out


def read_image(path: Path, yaml_path: Path) -> np.ndarray:
    if not path.is_file():
        raise MapFileError(f"{yaml_path}: key 'image': file {path} does not exist")
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)  # our message says it, in one line
    try:
        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    finally:
        cv2.utils.logging.setLogLevel(level)
    if img is None:
        raise MapFileError(f"{path}: not a readable image (PGM, PNG, ...)")
    if img.ndim == 3:  # map_server averages colour channels (alpha ignored)
        img = img[..., :3].mean(axis=2)
    if img.dtype == np.uint16:
        img = img / 257.0
    return np.asarray(img, np.float64)


def load_map(path) -> OccupancyGrid:
    """Read a map_server YAML and its image into an :class:`OccupancyGrid` (ROS row order)."""
    path = Path(path)
    meta = read_metadata(path)
    pixels = np.flipud(read_image(path.parent / meta["image"], path))
    if meta["mode"] == "raw":
        raw = np.rint(pixels).astype(np.int16)
        data = np.where(raw <= 100, raw, -1)
        states = states_from_ros(data, occupied_thresh=meta["occupied_thresh"], free_thresh=meta["free_thresh"])
    else:
        p = pixels / 255.0 if meta["negate"] else (255.0 - pixels) / 255.0
        states = np.full(p.shape, UNKNOWN_S, np.uint8)
        states[p < meta["free_thresh"]] = FREE_S
        states[p > meta["occupied_thresh"]] = OCCUPIED_S
    return OccupancyGrid(np.ascontiguousarray(states), meta["resolution"], tuple(meta["origin"][:2]))


def ensure_output_dir(path, option: str) -> None:
    """Make the folder ``path`` and check it is writable, before any work is done; a one-line
    :class:`MapFileError` naming ``option`` and the folder otherwise."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / ".write-test"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as e:
        raise MapFileError(f"{option} {path}: cannot write there ({e.strerror or e})") from None


def save_map(grid: OccupancyGrid, path, *, image_suffix: str = ".pgm") -> tuple[Path, Path]:
    """Write ``grid`` as map_saver does: ``<stem>.yaml`` and ``<stem>.pgm`` (free 254, occupied 0,
    unknown 205). ``path`` may name the YAML or the stem. Returns (yaml path, image path)."""
    path = Path(path)
    stem = path.with_suffix("") if path.suffix in (".yaml", ".yml", ".pgm") else path
    yaml_path, img_path = stem.with_suffix(".yaml"), stem.with_suffix(image_suffix)
    lut = np.array([PGM_UNKNOWN, PGM_FREE, PGM_OCCUPIED], np.uint8)
    img = np.flipud(lut[grid.states])
    yaml_path.parent.mkdir(parents=True, exist_ok=True)
    if image_suffix == ".pgm":
        header = f"P5\n# CREATOR: merger {grid.resolution:.3f} m/pix\n{grid.width} {grid.height}\n255\n"
        img_path.write_bytes(header.encode("ascii") + np.ascontiguousarray(img).tobytes())
    elif not cv2.imwrite(str(img_path), img):
        raise MapFileError(f"{img_path}: cannot write image")
    meta = {"image": img_path.name, "resolution": float(grid.resolution),
            "origin": [float(grid.origin[0]), float(grid.origin[1]), 0.0], "negate": 0,
            "occupied_thresh": 0.65, "free_thresh": 0.196, "mode": "trinary"}
    yaml_path.write_text(yaml.safe_dump(meta, default_flow_style=None, sort_keys=False))
    return yaml_path, img_path


def save_overlay(layers: list[OccupancyGrid], names: list[str], path) -> Path:
    """Write the thesis-style colour overlay (see :func:`merger.overlay.overlay_rgb`) as a PNG."""
    rgb = overlay_rgb([g.states for g in layers], names)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), cv2.cvtColor(np.flipud(rgb), cv2.COLOR_RGB2BGR)):
        raise MapFileError(f"{path}: cannot write PNG")
    return path
