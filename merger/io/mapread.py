"""A ROS map_server map's two files read and checked, before any cell state is decoded.

:func:`read_metadata` parses the YAML and checks its keys (``image``, ``resolution`` at least
:data:`MIN_RESOLUTION_M`, an unrotated ``origin`` within :data:`MAX_ORIGIN_M`, ``mode`` one of :data:`MODES`,
``negate``, the thresholds) and fills in map_server's defaults. Numbers may be written as YAML 1.2 allows
(``5e-2`` as well as ``0.05``). :func:`check_image_file` refuses, from the header alone, an image that is no
regular file or declares more than :data:`MAX_MAP_CELLS` cells or :data:`MAX_MAP_SIDE` a side (a few hundred
kB of PNG can decode to gigabytes); :func:`read_image` then decodes its grey levels. A PGM written by
map_saver states its resolution in a comment (``# CREATOR: map_saver.cpp 0.050 m/pix``): a YAML that says
otherwise is refused (:func:`check_image_resolution`).

Every problem with a file raises :class:`MapFileError` (one line naming the file and the key), the error of
every file :mod:`merger.io` reads or writes. :func:`merger.io.mapio.load_map` turns the grey levels into
cell states by map_server's rule.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import cv2
import numpy as np
import yaml

from ..limits import MAX_YAML_BYTES, InputLimitError, load_yaml, one_line, read_input

MODES = ("trinary", "scale", "raw")
MAX_ORIGIN_M = 1e6  # a map origin a thousand kilometres away is a typo
MIN_RESOLUTION_M = 1e-3  # a map of cells under a millimetre is a typo in its YAML
MAX_MAP_CELLS = 25_000_000  # cells of one map image (5000 x 5000: 250 m square at 5 cm), checked before decoding
MAX_MAP_SIDE = 32_000  # cells on a side (OpenCV's warps take fewer than 32,767)
_PGM_RESOLUTION = re.compile(rb"#[^\n]*?([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*m/pix")


class MapFileError(ValueError):
    """A map file that cannot be read as a ROS map_server map (message: ``file: problem``, one line)."""

    def __init__(self, message: str) -> None:
        super().__init__(one_line(message))


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
        raw = read_input(path, MAX_YAML_BYTES, "map YAML file")
    except OSError as e:
        raise MapFileError(f"{path}: cannot read: {e.strerror or e}") from None
    except InputLimitError as e:
        raise MapFileError(str(e)) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        hint = (" (this is an image: give the map's YAML, which names its image)"
                if raw[:2] in (b"P5", b"P2") or raw[:4] == b"\x89PNG" else "")
        raise MapFileError(f"{path}: expected a map_server YAML file (UTF-8 text), got binary data{hint}") from None
    try:
        meta = load_yaml(text)
    except yaml.YAMLError as e:
        raise MapFileError(f"{path}: not valid YAML: {str(e).splitlines()[0]}") from None
    except (ValueError, TypeError, RecursionError) as e:  # e.g. a date 2001-13-01, nesting too deep
        raise MapFileError(f"{path}: not valid YAML: {type(e).__name__}: {e}") from None
    if not isinstance(meta, dict):
        raise MapFileError(f"{path}: expected a YAML mapping with keys image, resolution, origin")
    if not isinstance(meta.get("image"), str) or not meta["image"]:
        raise MapFileError(f"{path}: key 'image': expected the image file name, got {meta.get('image')!r}")
    origin = meta.get("origin")
    if (not isinstance(origin, list) or len(origin) not in (2, 3)
            or not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                       and abs(v) <= MAX_ORIGIN_M for v in origin)):
        raise MapFileError(f"{path}: key 'origin': expected [x, y, yaw] of finite numbers (|x|, |y| at most "
                           f"{MAX_ORIGIN_M:g} m), got {origin!r}")
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
    if out["resolution"] < MIN_RESOLUTION_M:
        raise MapFileError(f"{path}: key 'resolution': expected a cell size of at least {MIN_RESOLUTION_M:g} m, "
                           f"got {out['resolution']:g}")
    if out["free_thresh"] >= out["occupied_thresh"]:
        raise MapFileError(f"{path}: key 'free_thresh': expected < occupied_thresh "
                           f"({out['occupied_thresh']}), got {out['free_thresh']}")
    return out


def image_size(path: Path) -> tuple[int, int] | None:
    """(width, height) of the image ``path`` from its header alone (Pillow reads no pixels), or None when
    Pillow does not know the format."""
    import warnings

    from PIL import Image, UnidentifiedImageError

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Pillow's decompression-bomb warning: our own limit is checked
        try:
            with Image.open(path) as im:
                return im.size
        except Image.DecompressionBombError as e:  # beyond twice Pillow's own limit: the size is in the text
            m = re.search(r"\((\d+) pixels", str(e))
            n = int(m.group(1)) if m else MAX_MAP_CELLS + 1
            return (n, 1)
        except (UnidentifiedImageError, OSError, ValueError, SyntaxError):
            return None


def check_image_file(path: Path, yaml_path: Path) -> None:
    """The image of ``yaml_path`` must be a regular file whose header declares at most :data:`MAX_MAP_CELLS`
    cells and :data:`MAX_MAP_SIDE` a side; checked before decoding (a few hundred kB of PNG can decode
    to gigabytes)."""
    import stat

    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise MapFileError(f"{yaml_path}: key 'image': file {path} does not exist") from None
    except OSError as e:
        raise MapFileError(f"{yaml_path}: key 'image': cannot read {path} ({e.strerror or e})") from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file (a FIFO, device or socket)"
        raise MapFileError(f"{yaml_path}: key 'image': {path} is {kind}: expected an image file")
    size = image_size(path)
    if size is None:
        raise MapFileError(f"{path}: not a readable image (expected PGM, PNG, BMP, JPEG, TIFF, ... whose size "
                           "can be read from its header)")
    w, h = size
    if w * h > MAX_MAP_CELLS or max(w, h) > MAX_MAP_SIDE:
        what = f"{w} x {h} cells" if h > 1 or w <= MAX_MAP_SIDE else f"{w} cells"
        raise MapFileError(f"{path}: an image of {what}: expected at most {MAX_MAP_CELLS} cells and "
                           f"{MAX_MAP_SIDE} a side (checked before decoding)")


def read_image(path: Path, yaml_path: Path) -> np.ndarray:
    check_image_file(path, yaml_path)
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)  # our message says it, in one line
    try:
        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    except cv2.error as e:  # e.g. a header declaring a size OpenCV refuses
        msg = str(e).strip().splitlines()[-1] if str(e).strip() else "OpenCV error"
        raise MapFileError(f"{path}: not a readable image ({msg.split('error: ')[-1]})") from None
    finally:
        cv2.utils.logging.setLogLevel(level)
    if img is None:
        raise MapFileError(f"{path}: not a readable image (PGM, PNG, ...)")
    if img.ndim == 3:  # map_server averages colour channels (alpha ignored)
        img = img[..., :3].mean(axis=2)
    return img  # grey levels as read (uint8, uint16) or a float64 mean: mapio._grey makes them 0..255


def pgm_resolution(path: Path) -> float | None:
    """The resolution a map_saver PGM states in its header comment (``0.050 m/pix``), if any."""
    try:
        with open(path, "rb") as f:
            head = f.read(512)
    except OSError:
        return None
    if not head.startswith((b"P5", b"P2")):
        return None
    m = _PGM_RESOLUTION.search(head)
    try:
        return float(m.group(1)) if m else None
    except ValueError:
        return None


def check_image_resolution(meta: dict, img_path: Path, yaml_path: Path) -> None:
    """A YAML resolution that contradicts its PGM's own statement is a wrong map, not a scale (map_saver
    prints 3 decimals: a difference under 0.0005 m is rounding)."""
    stated = pgm_resolution(img_path)
    if stated is not None and stated > 0 and not math.isclose(stated, meta["resolution"], rel_tol=1e-3, abs_tol=5e-4):
        raise MapFileError(f"{yaml_path}: key 'resolution': {meta['resolution']:g} m per cell, but its image "
                           f"{img_path.name} was saved at {stated:g} m/pix (header comment); correct the YAML")
