"""ROS map_server files (PGM/PNG image + YAML) and colour overlay PNGs.

Reading follows map_server: ``p = (255 − pixel)/255`` (``pixel/255`` with ``negate: 1``); in
``trinary`` and ``scale`` modes a cell is occupied when ``p > occupied_thresh``, free when
``p < free_thresh``, unknown otherwise; in ``raw`` mode the pixel value is the occupancy value
itself (0..100, anything else unknown). The image's top row is the max-y row (flipped into the ROS
grid order). Writing follows map_saver: P5 PGM with free 254, occupied 0, unknown 205.

The two files are read and checked by :mod:`merger.io.mapread` (the YAML's keys, the image's size before
decoding, a PGM's stated resolution); :func:`load_map` applies the rule above to what it reads. Every
problem with a file raises :class:`~merger.io.mapread.MapFileError` naming the file and the key.

Files are written atomically (a temporary file in the same folder, then :func:`os.replace`); the files
of one output (a map's YAML and image, a merge's map and overlay) appear all or none
(:func:`write_files`).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import cv2
import numpy as np
import yaml

from ..grid import FREE_S, OCCUPIED_S, UNKNOWN_S, OccupancyGrid, states_from_ros
from .mapread import MapFileError, check_image_resolution, read_image, read_metadata
from .overlay import overlay_picture

PGM_FREE, PGM_OCCUPIED, PGM_UNKNOWN = 254, 0, 205


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


def load_image_map(path, resolution: float, origin=(0.0, 0.0)) -> OccupancyGrid:
    """An image alone (no YAML) read as map_server reads one with map_server's defaults (``trinary``,
    ``negate: 0``, thresholds 0.65 / 0.196), at ``resolution`` metres per cell, cell (0, 0)'s corner
    at ``origin``. Problems raise :class:`~merger.io.mapread.MapFileError` naming the file."""
    path = Path(path)
    img = np.flipud(read_image(path, path))
    if img.size == 0:
        raise MapFileError(f"{path}: an empty image (0 cells)")
    meta = {"mode": "trinary", "negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.196}
    return OccupancyGrid(np.ascontiguousarray(_pixel_states(_grey(img), meta)), float(resolution),
                         (float(origin[0]), float(origin[1])))


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
