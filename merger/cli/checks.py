"""The command line's own checks: what only a command line has to check, each refusal a one-line
:class:`~merger.cli.parser.UsageError` naming the option.

Every check of a merge's inputs (the settings' rules, the maps on the first one's cells, each center near
its map, the limits) is the library's (:mod:`merger.inputs`, run by :func:`merger.api.prepare`); here they
are only named by the option the user typed (:class:`options_named`). What stays here is the command
line's own grammar: ``X,Y`` text, ``--center`` once or once per map, ``--bag`` with ``--topics``, output
stems and folders, and the demo's options.
"""

from __future__ import annotations

import math
from dataclasses import asdict
from pathlib import Path

from ..api import prepare
from ..inputs import MergeInputError, check_roi_cells
from ..io.inputs import map_names as _map_names
from ..team.params import MergeParams
from .parser import OPTIONS, UsageError

DEMO_MAX_RADIUS_M = 2.4  # the generated room (8 x 6 m, off-center by (0.7, 0.4)) holds a circle this big
DEMO_MAX_RADIUS_REAL_M = 5.0  # --real: the views are 12 m squares about each robot's start


def parse_xy(text: str, what: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        raise UsageError(f"{what}: expected X,Y in metres (e.g. 1.5,-0.25), got {text!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise UsageError(f"{what}: expected finite numbers, got {text!r}")
    return x, y


def check_roi(roi_m: float, resolution: float, path) -> None:
    """--roi in cells of the maps' resolution: the library's rule (:func:`merger.inputs.check_roi_cells`,
    the ROI's rule with the inputs' limits), named ``--roi``."""
    with options_named({}):
        check_roi_cells(roi_m, resolution, str(path))


def map_names(paths: list[Path]) -> list[str]:
    """One distinct name per map file (:func:`merger.io.inputs.map_names`)."""
    with options_named({}):
        return _map_names(paths)


class options_named:
    """Within it, a :class:`~merger.inputs.MergeInputError` becomes a :class:`UsageError` naming the input by
    this command line's option: ``keys`` maps the library's keys (``centers[1]``) to options, the merge
    settings are named by :data:`OPTIONS`, ``maps`` by ``merge``."""

    def __init__(self, keys: dict[str, str]) -> None:
        self.keys = {"maps": "merge", "centers": "--center", **{k: o for k, (o, _) in OPTIONS.items()}, **keys}

    def __enter__(self):
        return self

    def __exit__(self, kind, e, tb):
        if isinstance(e, MergeInputError):
            raise UsageError(str(e.named(self.keys.get(e.key, e.key)))) from None
        return False


def center_keys(centers: list) -> dict[str, str]:
    """How ``merger merge`` names each map's center: ``--center``, or ``--center (map i)`` when they differ."""
    one = len(set(centers)) == 1
    return {f"centers[{i}]": "--center" if one else f"--center (map {i + 1})" for i in range(len(centers))}


def centers_of(centers: list[str], n: int, what: str = "map") -> list[tuple[float, float]]:
    """--center once for all maps or once per map, each X,Y."""
    if len(centers) not in (1, n):
        raise UsageError(f"--center: expected once or once per {what} ({n}), got {len(centers)}")
    return [parse_xy(c, "--center") for c in centers] * (n if len(centers) == 1 else 1)


def file_inputs(paths: list[Path], centers: list[str], params: MergeParams):
    """The maps of ``merger merge FILE...``, checked by :func:`merger.api.prepare`: (MapInput list, notes)."""
    if len(paths) < 2:
        raise UsageError("merge: expected at least two maps (map_server YAML files, or --bag BAG --topics ...)")
    cs = centers_of(centers, len(paths))
    with options_named(center_keys(cs)):
        maps, _, notes = prepare(paths, cs, **asdict(params))
    return maps, notes


def bag_inputs(bag: Path, topics_arg: str | None, maps: list[Path], centers: list[str], params: MergeParams):
    """``--bag BAG --topics /r1/map,/r2/map``: the last map of each topic, named by its robot, checked by
    :func:`merger.api.prepare`."""
    from ..io.bagio import read_bag_maps, topic_names

    if maps:
        raise UsageError("--bag: give the maps either as files or as --bag with --topics, not both")
    topics = [t.strip() for t in (topics_arg or "").split(",") if t.strip()]
    if len(topics) < 2:
        raise UsageError(f"--topics: expected at least two map topics T1,T2,..., got {topics_arg!r}")
    if len(set(topics)) != len(topics):
        raise UsageError(f"--topics: a topic is given twice in {topics_arg!r}")
    cs = centers_of(centers, len(topics), "topic")
    grids = read_bag_maps(bag, topics)
    with options_named(center_keys(cs)):
        placed, _, notes = prepare([grids[t] for t in topics], cs, names=topic_names(topics),
                                   labels=[f"{bag}:{t}" for t in topics], **asdict(params))
    return placed, notes


def check_output_folder(path: Path, option: str) -> Path:
    """An output folder: a folder or nothing yet (not a file, a device, ...)."""
    if path.exists() and not path.is_dir():
        raise UsageError(f"{option} {path}: expected an output folder, got an existing file")
    return path


def check_stem(given: str | Path, option: str) -> Path:
    """An output stem (``out/merged``): a file name, not ``''``, ``.``, a folder's name ending in "/" or an
    existing folder. ``given`` as typed (a ``Path`` drops a trailing "/": ``Path("out/")`` is ``out``)."""
    path = Path(given)
    if path.name in ("", ".", "..") or str(given).endswith(("/", "\\")) or path.is_dir():
        raise UsageError(f"{option}: expected an output file stem such as out/merged (writes out/merged.yaml, "
                         f".pgm and _overlay.png), got {str(given)!r}" + (" (a folder)" if path.is_dir() else ""))
    return path


def check_demo_options(args, params: MergeParams) -> None:
    """``merger demo``'s own options: --arc, --radius, --center-error, --seed, --real-center."""
    if not (math.isfinite(args.arc) and 0 <= args.arc <= 180):
        raise UsageError(f"--arc: expected a number of degrees in [0, 180], got {args.arc:g}")
    top_r = DEMO_MAX_RADIUS_REAL_M if args.real else DEMO_MAX_RADIUS_M
    if args.radius is not None and not (math.isfinite(args.radius) and 0 < args.radius <= top_r):
        where = ("the robots' views are 12 m maps cut around their arcs" if args.real else
                 "the generated room is 8 x 6 m about the center")
        raise UsageError(f"--radius: expected a number of metres in (0, {top_r:g}] ({where}), got {args.radius:g}")
    top_e = params.roi_m / 2
    if not (math.isfinite(args.center_error) and 0 <= args.center_error <= top_e):
        raise UsageError(f"--center-error: expected a number of metres in [0, {top_e:g}] (half the --roi: "
                         f"farther, the ROI misses the true center), got {args.center_error:g}")
    if args.seed < 0:
        raise UsageError(f"--seed: expected an integer >= 0, got {args.seed}")
    if args.real_center and not args.real:
        raise UsageError("--real-center: only with --real MAP.yaml")


def real_scene(args, params: MergeParams):
    """``merger demo --real MAP``: the map, the common center (--real-center, checked to lie on the map, or
    the map's widest free point) and that point's clearance, metres: (world, center, clearance)."""
    from ..grid import FREE_S
    from ..io.mapio import load_map
    from ..synthetic import widest_free_point

    world = load_map(args.real)
    check_roi(params.roi_m, world.resolution, args.real)
    if not (world.states == FREE_S).any():  # nowhere to stand: the demo's robots need free space
        raise UsageError(f"--real {args.real}: the map has no free cell: expected a map with free space for "
                         "the robots to stand in")
    free_c, clearance = widest_free_point(world)
    if args.real_center:
        center = parse_xy(args.real_center, "--real-center")
        x0, x1, y0, y1 = world.extent
        if not (x0 <= center[0] <= x1 and y0 <= center[1] <= y1):
            raise UsageError(f"--real-center: ({center[0]:g}, {center[1]:g}) is outside {args.real}, which "
                             f"spans x [{x0:g}, {x1:g}], y [{y0:g}, {y1:g}] m: expected a point of the map "
                             f"(default: its widest free point, {free_c[0]:.2f},{free_c[1]:.2f})")
    else:
        center = free_c
    return world, center, clearance


def pair_names(ref: Path, moving: Path) -> tuple[str, str]:
    """The names ``merger merge REF MOVING`` gives the two maps (their stems), or "ref"/"moving" for one
    file given twice."""
    try:
        return tuple(map_names([ref, moving]))
    except UsageError:
        return "ref", "moving"
