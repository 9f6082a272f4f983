"""ROS map_server files (PGM/PNG image + YAML) and colour overlay PNGs.

Reading follows map_server: ``p = (255 − pixel)/255`` (``pixel/255`` with ``negate: 1``); in
``trinary`` and ``scale`` modes a cell is occupied when ``p > occupied_thresh``, free when
``p < free_thresh``, unknown otherwise; in ``raw`` mode the pixel value is the occupancy value
itself (0..100, anything else unknown). The image's top row is the max-y row (flipped into the ROS
grid order). Writing follows map_saver: P5 PGM with free 254, occupied 0, unknown 205.

Every problem with a file raises :class:`MapFileError` naming the file and the key. Numbers may be
written as YAML 1.2 allows (``5e-2`` as well as ``0.05``). A PGM written by map_saver states its
resolution in a comment (``# CREATOR: map_saver.cpp 0.050 m/pix``): a YAML that says otherwise is refused.

Files are written atomically (a temporary file in the same folder, then :func:`os.replace`); the files
of one output (a map's YAML and image, a merge's map and overlay) appear all or none
(:func:`write_files`).
"""

from __future__ import annotations

import math
import os
import re
import tempfile
from pathlib import Path

import cv2
import numpy as np
import yaml

from ..grid import FREE_S, OCCUPIED_S, UNKNOWN_S, OccupancyGrid, states_from_ros
from ..limits import MAX_YAML_BYTES, InputLimitError, load_yaml, one_line, read_input
from .overlay import overlay_picture

PGM_FREE, PGM_OCCUPIED, PGM_UNKNOWN = 254, 0, 205
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
    return img  # grey levels as read (uint8, uint16) or a float64 mean: _grey makes them 0..255


def _grey(img: np.ndarray) -> np.ndarray:
    """Grey levels 0..255 (float64) of an image's pixels: 16-bit ones scaled down."""
    return img / 257.0 if img.dtype == np.uint16 else np.asarray(img, np.float64)


def _pixel_states(pixels: np.ndarray, meta: dict) -> np.ndarray:
    """map_server's rule: the state of each grey level (0..255, float64) of ``pixels``."""
    if meta["mode"] == "raw":
        raw = np.rint(pixels).astype(np.int16)
        data = np.where(raw <= 100, raw, -1)
        return states_from_ros(data, occupied_thresh=meta["occupied_thresh"], free_thresh=meta["free_thresh"])
    p = pixels / 255.0 if meta["negate"] else (255.0 - pixels) / 255.0
    states = np.full(p.shape, UNKNOWN_S, np.uint8)
    states[p < meta["free_thresh"]] = FREE_S
    states[p > meta["occupied_thresh"]] = OCCUPIED_S
    return states


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


def load_map(path) -> OccupancyGrid:
    """Read a map_server YAML and its image into an :class:`OccupancyGrid` (ROS row order)."""
    path = Path(path)
    meta = read_metadata(path)
    img_path = path.parent / meta["image"]
    img = np.flipud(read_image(img_path, path))
    check_image_resolution(meta, img_path, path)
    if img.size == 0:
        raise MapFileError(f"{img_path}: an empty image (0 cells)")
    if img.dtype in (np.uint8, np.uint16):  # the rule once per grey level, then a look-up: the same states
        levels = np.arange(np.iinfo(img.dtype).max + 1, dtype=img.dtype)  # without float copies of the image
        states = _pixel_states(_grey(levels), meta)[img]
    else:
        states = _pixel_states(_grey(img), meta)
    return OccupancyGrid(np.ascontiguousarray(states), meta["resolution"], tuple(meta["origin"][:2]))


def map_input_paths(path) -> list[Path]:
    """The files a map is read from: its YAML and its image (for :func:`check_outputs`)."""
    path = Path(path)
    return [path, path.parent / read_metadata(path)["image"]]


def ensure_output_dir(path, option: str) -> None:
    """Make the folder ``path`` and check it is writable, before any work is done; a one-line
    :class:`MapFileError` naming ``option`` and the folder otherwise."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".write-test.", dir=path)  # unique: other processes check too
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise MapFileError(f"{option} {path}: cannot write there ({e.strerror or e})") from None


CENTERS_FILE = "centers.yaml"


def centers_yaml(maps: dict[str, dict], truth: dict[str, tuple] | None, command: str, note: str = "") -> bytes:
    """The ``centers.yaml`` written beside simulated or demo maps (``merger demo``, ``circsim run
    --save-maps``): for each map its file, the common center in its frame as given to the merger
    (``center``) and exact (``center_true``), the robot's start pose in the world (x, y, yaw in degrees);
    the ground truth of each map onto the first (``theta_deg``, ``translation_m``: x_first = c_first + t +
    R(θ)(x − c), with the given centers); and the ``merger merge`` command that merges the maps."""
    first = next(iter(maps))
    doc = {"note": note, "maps": maps}
    if truth is not None:
        doc["truth_onto"] = first
        doc["truth"] = {n: {"theta_deg": round(float(th), 6), "translation_m": [round(float(v), 6) + 0.0 for v in t]}
                        for n, (th, t) in truth.items()}
    doc["merge_command"] = command
    return yaml.safe_dump(_plain(doc), default_flow_style=None, sort_keys=False, allow_unicode=True,
                          width=4096).encode()


def merge_command(paths, centers, out, params=None) -> str:
    """The ``merger merge`` command line that merges ``paths`` with their ``centers`` (one per map) into
    ``out``, with the merge options of ``params`` (a :class:`merger.team.orders.MergeParams`) that differ from the
    defaults."""
    import shlex

    words = ["merger", "merge", *(str(p) for p in paths)]
    for x, y in centers:
        words += ["--center", f"{round(x, 6) + 0.0:.6f},{round(y, 6) + 0.0:.6f}"]  # no "-0.000000"
    d = type(params)() if params is not None else None  # the defaults: options that differ are written
    for opt, key in (("--roi", "roi_m"), ("--measure", "measure"), ("--method", "method"),
                     ("--window", "window_m"), ("--nu-min", "nu_min"), ("--min-support", "min_support")):
        if params is not None and getattr(params, key) != getattr(d, key):
            words += [opt, f"{getattr(params, key):g}" if isinstance(getattr(params, key), float)
                      else str(getattr(params, key))]
    if params is not None and not params.refine:
        words.append("--no-refine")
    if params is not None and not params.combine_orders:
        words.append("--no-combine-orders")
    words += ["-o", str(out)]
    return " ".join(shlex.quote(w) for w in words)


def _plain(v):
    """numpy scalars and tuples as plain YAML numbers and lists."""
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_plain(x) for x in v]
    if isinstance(v, np.generic):
        return v.item()
    return v


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_files(files: dict) -> list[Path]:
    """Write ``{path: bytes}`` all or none: every file goes to a temporary name in its folder first, and
    only when all are written are they renamed (:func:`os.replace`) into place. A failure removes the
    temporary files and raises :class:`MapFileError` naming the file; a reader never sees half a file."""
    import stat

    for path in files:
        try:
            st = os.lstat(path)
        except OSError:
            continue
        if stat.S_ISDIR(st.st_mode):
            raise MapFileError(f"{path}: cannot write: a folder has that name")
        if not stat.S_ISREG(st.st_mode):
            raise MapFileError(f"{path}: cannot write: it is a symbolic link or a special file (refusing to "
                               "replace it)")
    temps: list[tuple[str, Path]] = []
    placed: list[Path] = []
    try:
        for path, data in files.items():
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
            temps.append((tmp, path))
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            os.chmod(tmp, 0o666 & ~_umask())  # mkstemp's 0600 would make the map private
        for tmp, path in temps:
            os.replace(tmp, path)
            placed.append(path)
    except BaseException as e:  # a full disk, or Ctrl-C meanwhile: no temporary file is left behind
        for p in placed:  # a rename failed after others: take those back (none or all)
            p.unlink(missing_ok=True)
        for tmp, _ in temps:
            try:
                os.unlink(tmp)
            except OSError:
                pass
        if not isinstance(e, OSError):
            raise
        raise MapFileError(f"{e.filename or path}: cannot write ({e.strerror or e})") from None
    return [p for _, p in temps]


def map_paths(path, image_suffix: str = ".pgm") -> tuple[Path, Path]:
    """(YAML path, image path) of the map ``path`` names: the YAML or the stem. A stem keeps its dots
    (``out/run_w0.5`` → ``out/run_w0.5.yaml``, not ``out/run_w0.yaml``)."""
    path = Path(path)
    stem = path.with_suffix("") if path.suffix in (".yaml", ".yml", ".pgm") else path
    return stem.with_name(stem.name + ".yaml"), stem.with_name(stem.name + image_suffix)


def check_outputs(outputs: dict, inputs: dict | None = None) -> None:
    """Refuse, before any work, outputs that would destroy data: ``outputs`` (a mapping or (path, what)
    pairs) and ``inputs`` map paths to the option or file that names them. An output may not be an input (or its image), another output, a
    folder, a symbolic link or another non-regular file (device, FIFO, socket); :class:`MapFileError`
    naming both otherwise. (Outputs are then written by :func:`write_files`: temporary file, rename.)"""
    import stat

    def key(p):
        return os.path.normcase(os.path.realpath(p))

    ins = {key(p): (p, what) for p, what in (inputs or {}).items()}
    seen: dict[str, tuple] = {}
    for p, what in (outputs.items() if isinstance(outputs, dict) else outputs):
        p = Path(p)
        if p.name in ("", ".", ".."):
            raise MapFileError(f"{what}: expected a file name, got {str(p)!r}")
        try:
            st = os.lstat(p)
        except FileNotFoundError:
            st = None
        except OSError as e:
            raise MapFileError(f"{what} {p}: cannot write there ({e.strerror or e})") from None
        if st is not None and not stat.S_ISREG(st.st_mode):
            kind = ("a folder" if stat.S_ISDIR(st.st_mode) else "a symbolic link" if stat.S_ISLNK(st.st_mode)
                    else "not a regular file (a device, FIFO or socket)")
            raise MapFileError(f"{what} {p}: is {kind}: expected a regular file to create or replace "
                               "(refusing to replace it)")
        k = key(p)
        if k in ins:
            q, w = ins[k]
            raise MapFileError(f"{what} {p}: is also an input ({w} {q}): expected a different output path")
        if k in seen:
            q, w = seen[k]
            raise MapFileError(f"{what} {p}: is also written by {w} ({q}): expected distinct outputs")
        seen[k] = (p, what)


def map_files(grid: OccupancyGrid, path, *, image_suffix: str = ".pgm") -> dict[Path, bytes]:
    """The files of ``grid`` as map_saver writes them: ``{<stem>.yaml: ..., <stem>.pgm: ...}`` (free 254,
    occupied 0, unknown 205). ``path`` may name the YAML or the stem (:func:`map_paths`)."""
    yaml_path, img_path = map_paths(path, image_suffix)
    lut = np.array([PGM_UNKNOWN, PGM_FREE, PGM_OCCUPIED], np.uint8)
    img = np.flipud(lut[grid.states])
    if image_suffix == ".pgm":
        header = f"P5\n# CREATOR: merger {grid.resolution:.6g} m/pix\n{grid.width} {grid.height}\n255\n"
        data = header.encode("ascii") + np.ascontiguousarray(img).tobytes()
    else:
        ok, buf = cv2.imencode(image_suffix, img)
        if not ok:
            raise MapFileError(f"{img_path}: cannot encode the image as {image_suffix}")
        data = buf.tobytes()
    meta = {"image": img_path.name, "resolution": float(grid.resolution),
            "origin": [float(grid.origin[0]), float(grid.origin[1]), 0.0], "negate": 0,
            "occupied_thresh": 0.65, "free_thresh": 0.196, "mode": "trinary"}
    return {img_path: data,
            yaml_path: yaml.safe_dump(meta, default_flow_style=None, sort_keys=False).encode()}


def save_map(grid: OccupancyGrid, path, *, image_suffix: str = ".pgm") -> tuple[Path, Path]:
    """Write ``grid`` as map_saver does (see :func:`map_files`), both files or none. Returns (yaml path,
    image path)."""
    img_path, yaml_path = write_files(map_files(grid, path, image_suffix=image_suffix))
    return yaml_path, img_path


def overlay_png(layers: list[OccupancyGrid], names: list[str], *, title: str = "", cell_px: int | None = None) -> bytes:
    """The thesis-style colour overlay as a PNG for people (:func:`merger.io.overlay.overlay_picture`: cropped to
    the known cells, 4 px per cell, ``title``, legend of robot colours, 1 m scale bar)."""
    rgb = overlay_picture([g.states for g in layers], names, layers[0].resolution, title=title, cell_px=cell_px)
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 image as PNG
        raise MapFileError("cannot encode the overlay as PNG")
    return buf.tobytes()


def save_overlay(layers: list[OccupancyGrid], names: list[str], path, *, title: str = "",
                 cell_px: int | None = None) -> Path:
    """Write the thesis-style colour overlay as a PNG (see :func:`overlay_png`)."""
    return write_files({Path(path): overlay_png(layers, names, title=title, cell_px=cell_px)})[0]
