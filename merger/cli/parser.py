"""The command line's parser: ``merger align | merge | demo`` and their options.

:func:`build_parser` is the whole grammar; a parse error is a :class:`UsageError` (one line, exit 2: see
:func:`merger.cli.main`), not argparse's usage block. :data:`OPTIONS` maps each merge setting of
:class:`~merger.team.params.MergeParams` to its option: the options' defaults are MergeParams's and their
values are checked by each setting's one rule (:func:`merger.cli.params_from`). :func:`join_negative_xy`
lets ``--center -1.2,0.5`` through argparse.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from ..algorithms import ALGORITHMS
from ..algorithms import DEFAULT as DEFAULT_ALGORITHM
from ..io.mapread import MAX_MAP_CELLS, MAX_MAP_SIDE, MIN_RESOLUTION_M
from ..limits import MAX_ROI_M
from ..measures import MEASURES
from ..search import SEARCH_METHODS
from ..settings import MAX_ROI_CELLS
from ..team.defaults import VERIFICATIONS_BY_NAME
from ..team.params import RULES, MergeParams

XY_OPTIONS = ("--center", "--center-moving", "--real-center")
_NEGATIVE_XY = re.compile(r"^-\s*(\d|\.\d|inf|nan)[^,]*,.*$", re.IGNORECASE)


class UsageError(Exception):
    pass


def package_version() -> str:
    """The installed distribution's version (merger ships in the ``circsim`` distribution)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("circsim")
    except PackageNotFoundError:  # pragma: no cover - run from a source tree without installing
        return "unknown (not installed)"


def join_negative_xy(argv: list[str]) -> list[str]:
    """``--center -1.2,0.5`` → ``--center=-1.2,0.5`` (also ``--center-moving``, ``--real-center``).

    argparse takes a value starting with '-' for an option unless it is a plain negative number, so the
    natural spelling of a negative center (ROS map frames mostly have one) would fail with "expected one
    argument". A token after one of these options that looks like a pair X,Y with a negative X is joined
    to it; anything after ``--`` is left alone."""
    out, i = [], 0
    while i < len(argv):
        a = argv[i]
        if a == "--":
            out.extend(argv[i:])
            break
        if a in XY_OPTIONS and i + 1 < len(argv) and _NEGATIVE_XY.match(argv[i + 1]):
            out.append(f"{a}={argv[i + 1]}")
            i += 2
            continue
        out.append(a)
        i += 1
    return out


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2 (argparse prints usage + message otherwise)
        raise UsageError(message)




# The merge options: MergeParams's setting -> (option, argparse dest). Their defaults are MergeParams's and
# their values are checked by each setting's one rule (merger.team.params.RULES), named by the option.
OPTIONS = {"roi_m": ("--roi", "roi"), "measure": ("--measure", "measure"), "method": ("--method", "method"),
           "window_m": ("--window", "window"), "refine": ("--no-refine", "refine"),
           "refine_whole": ("--no-refine-whole", "refine_whole"),
           "combine_orders": ("--no-combine-orders", "combine_orders"), "nu_min": ("--nu-min", "nu_min"),
           "min_support": ("--min-support", "min_support"), "verification": ("--verification", "verification"),
           "tolerance_m": ("--tolerance", "tolerance"), "contrast_min": ("--contrast-min", "contrast_min"),
           "roi_min_support": ("--roi-min-support", "roi_min_support")}
# --verification: every whole-map rule (roi_score, the thesis's cross-correlation rule, has no --score-min)
CLI_VERIFICATIONS = tuple(v for v, rule in VERIFICATIONS_BY_NAME.items() if rule.whole_maps)


def add_merge_options(p: argparse.ArgumentParser, *, orders: bool = True) -> None:
    """The options of a merge; ``orders``: also those about merge orders (not for ``align``: one pair)."""
    d = MergeParams()
    p.add_argument("--roi", type=float, default=d.roi_m, metavar="M",
                   help=f"side of the square region of interest, metres, at most {MAX_ROI_M:g} and {MAX_ROI_CELLS} "
                        f"cells of the maps (default {d.roi_m})")
    p.add_argument("--measure", choices=MEASURES, default=d.measure,
                   help=f"what the search maximizes on the ROI: similarity (the thesis's ω̃), birk_carpin (ω, "
                        f"counts free/free) or ncc (cross-correlation of occupied cells) (default {d.measure})")
    p.add_argument("--method", choices=sorted(SEARCH_METHODS), default=d.method,
                   help=f"fast: the branch and bound; reference: the compiled exhaustive search, the same "
                        f"answer, far slower; spec: its numpy definition (small maps; tests) (default {d.method})")
    p.add_argument("--window", type=float, default=d.window_m, metavar="M",
                   help=f"the centers are trusted to ±M metres on each axis: the search covers every translation "
                        f"within it jointly with the rotation (default {d.window_m}; 0 = rotation only, the "
                        f"thesis's search; at most a quarter of --roi)")
    p.add_argument("--no-refine", dest="refine", action="store_false", default=d.refine,
                   help="report the search grid's answer (θ on the 0.1° grid, t in whole cells) without the "
                        "sub-cell refinement")
    p.add_argument("--no-refine-whole", dest="refine_whole", action="store_false", default=d.refine_whole,
                   help="merge at the search's placement instead of its refinement on the whole maps (the "
                        "thesis; by default a placement the contrast rule accepted is refined within ±5° and "
                        "±1 m, at most twice --window, and the search's is reported beside it)")
    if orders:
        p.add_argument("--no-combine-orders", dest="combine_orders", action="store_false", default=d.combine_orders,
                       help="keep the highest-Σν order's own placement (the thesis's rule) instead of the "
                            "mean of the accepted orders that agree with it, verified")
    p.add_argument("--nu-min", type=float, default=d.nu_min,
                   help=f"verification threshold, {RULES['nu_min'].expected} (default {d.nu_min})")
    p.add_argument("--min-support", type=int, default=d.min_support,
                   help=f"minimum agr̃+dis on whole maps, {RULES['min_support'].expected} (default {d.min_support})")
    p.add_argument("--verification", choices=CLI_VERIFICATIONS, default=d.verification,
                   help="whole_map: whole-map ω̃ ≥ --nu-min (the thesis); contrast: for maps from independent runs "
                        "(real maps), the whole-map fit within --tolerance must stand --contrast-min times above "
                        "the best rival placement and peak within 4° of the answer; auto: accepted when either "
                        f"accepts (docs/merging-real-maps.md; default {d.verification})")
    p.add_argument("--tolerance", type=float, default=d.tolerance_m, metavar="M",
                   help=f"contrast: walls this close count as agreeing, metres, {RULES['tolerance_m'].expected} "
                        f"(default {d.tolerance_m})")
    p.add_argument("--contrast-min", type=float, default=d.contrast_min,
                   help=f"contrast: the fit over the best rival's it needs, {RULES['contrast_min'].expected} "
                        f"(default {d.contrast_min})")
    p.add_argument("--roi-min-support", type=int, default=d.roi_min_support, metavar="CELLS",
                   help=f"the search's support floor: placements whose ROI agr̃+dis is below it score 0, so no "
                        f"answer rests on a handful of cells; {RULES['roi_min_support'].expected} (default "
                        f"{d.roi_min_support}; 0: "
                        f"the thesis's measure)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="merger", description="Merge occupancy grid maps of robots sharing a common center.",
                epilog="Limits (checked before any work; docs/limits.md): map YAML files up to 1 MiB, map images up "
                       f"to {MAX_MAP_CELLS:,} cells ({MAX_MAP_SIDE} a side), cells of at least {MIN_RESOLUTION_M:g} "
                       f"m, --roi up to {MAX_ROI_M:g} m and {MAX_ROI_CELLS} cells a side, centers within half "
                       "the ROI of their map. Errors: one line, exit 2.")
    p.add_argument("--version", action="version", version=f"merger {package_version()}")
    sub = p.add_subparsers(dest="cmd", required=True, parser_class=_Parser)
    a = sub.add_parser("align", help="find the rotation of MOVING onto REF about the common center")
    a.add_argument("ref", type=Path, help="reference map (map_server YAML)")
    a.add_argument("moving", type=Path, help="moving map (map_server YAML)")
    a.add_argument("--center", required=True, metavar="X,Y",
                   help="common center X,Y in REF's frame (and MOVING's), e.g. --center -1.2,0.5")
    a.add_argument("--center-moving", metavar="X,Y", help="common center X,Y in MOVING's frame, when it differs")
    add_merge_options(a, orders=False)
    m = sub.add_parser("merge", help="merge N ≥ 2 maps in all orders and write the verified result")
    m.add_argument("maps", type=Path, nargs="*", help="maps (map_server YAML); results in the first one's frame")
    m.add_argument("--bag", type=Path, metavar="BAG", help="read the maps from a ROS 2 bag instead (the last "
                   "nav_msgs/msg/OccupancyGrid of each --topics topic; needs the bag extra: rosbags)")
    m.add_argument("--topics", metavar="T1,T2,...", help="with --bag: the map topics, e.g. /r1/map,/r2/map,/r3/map "
                   "(results in the first one's frame; maps named r1, r2, ...)")
    m.add_argument("--center", action="append", required=True, metavar="X,Y",
                   help="common center X,Y: once for all maps, or once per map in order")
    m.add_argument("-o", "--output", type=str, required=True, help="output stem: writes OUT.yaml/.pgm and OUT_overlay.png")
    m.add_argument("--force", action="store_true", help="write the best hypothesis even if verification rejects it")
    m.add_argument("--algorithm", choices=ALGORITHMS, default=DEFAULT_ALGORITHM,
                   help="thesis (default): the search about the common center, verified; features: ROS m-explore "
                        "map_merge's ORB/RANSAC pipeline; hough: Carpin's Hough-spectrum merging (both use no "
                        "center, and only --min-support of the options: merger.algorithms)")
    add_merge_options(m)
    d = sub.add_parser("demo", help="three robots' partial maps of a generated scene (or of a saved map, "
                                     "--real), saved and merged")
    d.add_argument("-o", "--output", type=Path, default=Path("out/merger-demo"), help="output folder")
    d.add_argument("--seed", type=int, default=7, help="the scene's, the robots' and the center errors' random "
                   "seed, an integer >= 0 (default 7): the same seed gives the same maps")
    d.add_argument("--arc", type=float, default=30.0, help="each robot's displacement ±φ in degrees")
    d.add_argument("--real", type=Path, metavar="MAP.yaml",
                   help="cut the robots' views out of this saved map (ROS map_server) instead of a generated "
                        "scene: rays marched through it from the robots' arcs, re-rasterized in each robot's frame")
    d.add_argument("--real-center", metavar="X,Y", help="with --real: the common center in the map's frame "
                   "(default: the free point farthest from any obstacle)")
    d.add_argument("--radius", type=float, help="robots' circle radius in metres (default 1.8; with --real: "
                   "0.8 × the center's clearance, at most 1.8)")
    d.add_argument("--center-error", type=float, default=0.0, metavar="M",
                   help="give the merger each robot's center off by a random offset of up to ±M metres on each "
                        "axis (default 0: exact), to show the translation window recovering it")
    add_merge_options(d)
    return p

