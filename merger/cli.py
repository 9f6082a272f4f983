"""Command line: ``merger align``, ``merger merge`` and ``merger demo``.

A user's mistake (bad file, bad argument) prints one line ``merger: error: ...`` and exits with 2, before
any work and with nothing written. The limits it checks are :mod:`merger.limits` (shared with circsim);
the file formats are :mod:`merger.io`.

Why this module is longer than ~400 lines: it is the whole command line — the parser, the argument
checks the three commands share (centers, ROI, merge options, outputs) and the three commands, each a
short function over the library's API. Split it into a ``merger/cli/`` package when a fourth command
comes; until then one file shows every option and its check together.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from dataclasses import asdict
from pathlib import Path

import numpy as np

from .algorithms import ALGORITHMS
from .algorithms import DEFAULT as DEFAULT_ALGORITHM
from .api import merge_inputs, prepare, result_of
from .inputs import MergeInputError
from .io.inputs import map_names as _map_names
from .io.mapio import (
    CENTERS_FILE,
    centers_yaml,
    check_outputs,
    ensure_output_dir,
    load_map,
    map_files,
    map_input_paths,
    map_paths,
    merge_command,
    overlay_png,
    write_files,
)
from .io.mapread import MAX_MAP_CELLS, MAX_MAP_SIDE, MIN_RESOLUTION_M, MapFileError
from .limits import MAX_ROI_M
from .measures import MEASURES
from .search import SEARCH_METHODS
from .settings import MAX_ROI_CELLS, check_window
from .settings import check_roi as roi_rule
from .team.orders import MapInput, MergeParams, merge_team
from .team.params import RULES, VERIFICATIONS
from .team.pool import threads
from .team.verify import no_evidence
from .transform import rotation
from .verdict import RULE_NAMES, evidence_text, refusal, rule_of

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


def parse_xy(text: str, what: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        raise UsageError(f"{what}: expected X,Y in metres (e.g. 1.5,-0.25), got {text!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise UsageError(f"{what}: expected finite numbers, got {text!r}")
    return x, y


def check_roi(roi_m: float, resolution: float, path) -> None:
    """--roi in cells of the maps' resolution (the ROI's rule with the inputs' limits,
    :func:`merger.settings.check_roi`)."""
    try:
        roi_rule(roi_m, resolution, "--roi", limits=True, cells_of=str(path))
    except ValueError as e:
        raise UsageError(str(e)) from None


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
CLI_VERIFICATIONS = tuple(v for v in VERIFICATIONS if v != "roi_score")


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
    m.add_argument("-o", "--output", type=Path, required=True, help="output stem: writes OUT.yaml/.pgm and OUT_overlay.png")
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


def params_from(args) -> MergeParams:
    """The merge parameters of the command line (:data:`OPTIONS`; a command without an option takes
    MergeParams's default), every value checked first by its setting's one rule, named by its option (a
    one-line error); MergeParams's own ValueError is the last line of defence."""
    values = {name: getattr(args, dest) for name, (_, dest) in OPTIONS.items() if hasattr(args, dest)}
    try:
        roi_rule(args.roi, key="--roi", limits=True)  # the ROI's rule with the inputs' limits (merger.inputs)
        for name, v in values.items():
            RULES[name](v, OPTIONS[name][0])
        check_window(args.window, args.roi, "--window", "the --roi side")  # the rule between the two
    except ValueError as e:
        raise UsageError(str(e)) from None
    try:
        return MergeParams(**values)
    except ValueError as e:
        raise UsageError(f"invalid merge parameters: {e}") from None


def _xy(v) -> str:
    return f"({v[0]:.3f}, {v[1]:.3f})"


def pair_names(ref: Path, moving: Path) -> tuple[str, str]:
    """The names ``merger merge REF MOVING`` gives the two maps (their stems), or "ref"/"moving" for one
    file given twice."""
    try:
        return tuple(map_names([ref, moving]))
    except UsageError:
        return "ref", "moving"


def cmd_align(args) -> int:
    """MOVING searched onto REF and judged by every check of ``merger merge`` (the one order (0, 1) of
    :func:`merge_team`: the ambiguity rule's runner-up, the verification, the guard beyond the window):
    align accepts exactly what merge would accept of that search."""
    params = params_from(args)
    c_ref = parse_xy(args.center, "--center")
    c_mov = parse_xy(args.center_moving, "--center-moving") if args.center_moving else c_ref
    names = pair_names(args.ref, args.moving)
    moving_key = "--center-moving" if args.center_moving else "--center"
    with options_named({"centers[0]": "--center", "centers[1]": moving_key}):
        maps, params, notes = prepare([args.ref, args.moving], [c_ref, c_mov], names=names, **asdict(params))
    merged = merge_inputs(maps, params, notes)
    res = merged.team
    o = res.top
    al = o.steps[0][1]
    where = {"ref": str(args.ref), "moving": str(args.moving), "center_ref": list(c_ref),
             "center_moving": list(c_mov), "resampled": notes}
    if not al.has_evidence:
        why = no_evidence(al, params.roi_min_support)
        if args.json:
            print(json.dumps({**al.to_dict(), **where, "verdict": "no_evidence", "rule": "no_evidence",
                              "reason": why}))
        else:
            print(f"no evidence  {why}")
        return 1
    v = next(iter(o.checks.values()))
    out = {**al.to_dict(), **where, "verdict": "accepted" if res.accepted else "rejected", "rule": res.rule,
           "reason": res.reason,
           "verification": {**v.to_dict(), "nu_min": params.nu_min, "min_support": params.min_support,
                            "accepted": v.passed}, "decided_by": merged.rule,
           "pose": merged.poses[names[1]].to_dict(), "search_pose": merged.search_poses[names[1]].to_dict()}
    if res.chosen is not None and res.chosen.search_theta_deg:  # accepted by the contrast rule: refined
        out["refined_placement"] = {"theta_deg": res.chosen.theta_deg[names[1]],
                                    "translation_m": list(res.chosen.translation(names[1]))}
    if args.json:
        print(json.dumps(out))
        return 0 if res.accepted else 1
    for note in notes:
        print(f"note         {note}")
    tx, ty = al.translation_m
    c_target = (c_ref[0] + tx, c_ref[1] + ty)  # where MOVING's center lands in REF's frame
    # REF's center in MOVING's frame implied by (θ, t): x_ref = c_ref + R(θ)(x_moving − c_mov')
    d = rotation(-al.theta_deg) @ np.array([tx, ty])
    c_mov_fix = (c_mov[0] - d[0], c_mov[1] - d[1])
    how = f"window ±{params.window_m:g} m, " if params.window_m > 0 else "rotation only (--window 0), "
    how += (f"refined from the grid answer {al.theta_grid_deg:.1f} deg, {_xy(al.translation_grid_m)} m"
            if al.refined else "grid answer: 0.1 deg, whole cells")
    print(f"theta        {al.theta_deg:9.2f} deg   (x_ref = c_ref + t + R(theta)(x_moving - c_moving))")
    print(f"translation  {tx:+.3f}, {ty:+.3f} m  ({how})")
    print(f"             MOVING's center lands at {_xy(c_target)} in REF's frame; given REF center "
          f"{_xy(c_ref)}: correction ({tx:+.3f}, {ty:+.3f}) m")
    print(f"             equivalently, with REF's center exact, MOVING's center is {_xy(c_mov_fix)} "
          f"in its own frame (given {_xy(c_mov)})")
    print(f"score        {al.score:9.3f}       ({al.measure} on the {params.roi_m:g} m ROI; "
          f"agree {al.counts.agree}, disagree {al.counts.disagree})")
    print(f"runner-up    {al.runner_up_deg:9.1f} deg   score {al.runner_up_score:.3f}"
          + ("" if al.evidence.get("runner_up") == "exact" else
             "   (an upper bound: the search's envelope)" if al.evidence.get("runner_up") == "upper_envelope"
             else "   (approximate)"))
    print(f"verify       {rule_of([v])}: {evidence_text(v)}: {'passed' if v.passed else 'failed'}")
    print("verdict      " + ("ACCEPTED" if res.accepted else f"REJECTED by {refusal(res)}")
          + "   (every check of `merger merge`)")
    if "refined_placement" in out:
        r = out["refined_placement"]
        print(f"refined      {r['theta_deg']:9.2f} deg, t {_xy(r['translation_m'])} m   (the placement refined on the "
              f"whole maps, where `merger merge` draws the merged map)")
    p = merged.poses[names[1]]
    print(f"pose         x {p.x:+.3f} m, y {p.y:+.3f} m, yaw {p.yaw_deg:.2f} deg   (MOVING's frame in REF's: "
          "p_ref = R(yaw) p_moving + (x, y)" + ("" if res.accepted else "; rejected") + ")")
    return 0 if res.accepted else 1


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
    from .io.bagio import read_bag_maps, topic_names

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


def order_mark(o, res) -> str:
    """An order's verdict in the text output: never "accepted" for what the cycle then refuses."""
    if o is res.chosen:
        return "accepted"
    if not o.accepted:
        return f"rejected: {o.reason}"
    if res.chosen is not None:
        return "verified, not chosen" + (" (averaged into the chosen)" if o.order in res.chosen.combined else "")
    return f"verified, but the cycle is rejected by {RULE_NAMES[res.rule]} (below)"


def verdict_line(merged) -> str:
    """The cycle's verdict (a :class:`~merger.api.MergeResult`): the chosen order and the rule that accepted
    it with its figures, or the rule that refused it and its figures."""
    if merged.accepted:
        return f"chosen: {'→'.join(merged.team.chosen.order)} (accepted by {merged.rule}" \
            + (f": {merged.reason})" if merged.reason else ")")
    return f"REJECTED by {merged.rule}: {merged.reason}"


def pose_lines(merged) -> list[str]:
    """Each map's pose in the first map's frame (p_first = R(yaw)·p + (x, y)): what a tf needs."""
    word = "" if merged.accepted else " (the best rejected hypothesis)"
    return [f"pose{word}: {n} in {merged.frame}'s frame: x {p.x:+.3f} m, y {p.y:+.3f} m, yaw {p.yaw_deg:.2f}°"
            for n, p in merged.poses.items() if n != merged.frame]


def report_merge(merged, as_json: bool, extra: dict | None = None) -> None:
    """Print a merge (a :class:`~merger.api.MergeResult`): every order, the verdict, each map's pose."""
    res = merged.team
    if as_json:
        print(json.dumps({**res.to_dict(), "decided_by": merged.rule,
                          "poses": {k: p.to_dict() for k, p in merged.poses.items()},
                          "search_poses": {k: p.to_dict() for k, p in merged.search_poses.items()},
                          **(extra or {})}))
        return
    for o in res.orders:  # two lines per order: verdict, then each map's placement onto the first map
        ev = ", ".join(evidence_text(v, k) for k, v in o.checks.items())
        star = "*" if o is res.chosen else " "
        print(f"{star} order {'→'.join(o.order):<28} {ev}  [{order_mark(o, res)}]")
        print("      " + "; ".join(f"{k} {v:.2f}° t ({o.translation(k)[0]:+.3f}, {o.translation(k)[1]:+.3f}) m"
                                   for k, v in o.theta_deg.items() if k != res.frame))
        if o.search_theta_deg:  # the placement above is the search's refined on the whole maps
            st = o.search_translation_m
            print("      the search's: " + "; ".join(f"{k} {v:.2f}° t ({st[k][0]:+.3f}, {st[k][1]:+.3f}) m"
                                                  for k, v in o.search_theta_deg.items() if k != res.frame)
                  + " (refined on the whole maps to the line above)")
    print(f"merge cycle {res.wall_ms:.0f} ms; {verdict_line(merged)}")
    for line in pose_lines(merged):
        print(line)


def merge_files(res, maps: list[MapInput], out: Path, force: bool) -> dict[Path, bytes]:
    """The merged map (OUT.yaml/.pgm) and its overlay (OUT_overlay.png) as {path: bytes}; none when no order
    passed verification and ``force`` is off."""
    from .team.frames import fused_layers
    from .team.superpose import fuse

    if res.accepted:
        merged, layers = res.merged, [res.layers[m.name] for m in maps]
    elif force:
        layers = fused_layers(maps, res.top.theta_deg, res.top.translation_m)
        merged = type(layers[0])(fuse([g.states for g in layers]), layers[0].resolution, layers[0].origin)
    else:
        return {}
    files = map_files(merged, out)
    files[overlay_path(map_paths(out)[0])] = overlay_png(layers, [m.name for m in maps],
                                                             title=overlay_title(res))
    return files


DEMO_MAX_RADIUS_M = 2.4  # the generated room (8 x 6 m, off-center by (0.7, 0.4)) holds a circle this big
DEMO_MAX_RADIUS_REAL_M = 5.0  # --real: the views are 12 m squares about each robot's start


def check_output_folder(path: Path, option: str) -> Path:
    """An output folder: a folder or nothing yet (not a file, a device, ...)."""
    if path.exists() and not path.is_dir():
        raise UsageError(f"{option} {path}: expected an output folder, got an existing file")
    return path


def overlay_path(yaml_path: Path) -> Path:
    """OUT_overlay.png beside OUT.yaml (the stem keeps its dots)."""
    return yaml_path.with_name(yaml_path.name.removesuffix(".yaml") + "_overlay.png")


def check_stem(path: Path, option: str) -> Path:
    """An output stem (``out/merged``): a file name, not ``''``, ``.`` or an existing folder."""
    if path.name in ("", ".", "..") or str(path).endswith("/") or path.is_dir():
        raise UsageError(f"{option}: expected an output file stem such as out/merged (writes out/merged.yaml, "
                         f".pgm and _overlay.png), got {str(path)!r}" + (" (a folder)" if path.is_dir() else ""))
    return path


def overlay_title(res) -> str:
    """ASCII lines for the overlay picture (OpenCV's fonts have no θ, ν, →): the order shown, each map's
    angle and the verdict (with the rule that decided); then the evidence of that rule, pair by pair
    (:func:`evidence_text`)."""
    o = res.chosen or res.top
    th = ", ".join(f"{k} {v:.1f}" for k, v in o.theta_deg.items() if k != res.frame)
    if res.chosen is not None:
        verdict = f"ACCEPTED by {rule_of(o.checks.values())}"
    else:
        verdict = f"REJECTED, written with --force: {refusal(res)}"
    evidence = "; ".join(evidence_text(v, k) for k, v in o.checks.items())
    return ascii_text(f"{'>'.join(o.order)}  theta deg: {th}  {verdict}\n{evidence}")


_ASCII = {"ν": "nu", "ω̃": "omega", "ω": "omega", "θ": "theta", "φ": "phi", "Δ": "d", "→": ">", "≥": ">=",
          "≤": "<=", "×": "x", "°": " deg", "−": "-", "–": "-", "—": "-", "±": "+-", "…": "..."}


def ascii_text(text: str) -> str:
    """``text`` in ASCII for OpenCV's fonts: the merger's symbols spelt out, anything else as '?'."""
    for k, v in _ASCII.items():
        text = text.replace(k, v)
    return text.encode("ascii", "replace").decode("ascii")


def write_merge(res, maps: list[MapInput], out: Path, force: bool) -> list[Path]:
    """Write :func:`merge_files`, all or none."""
    return write_files(merge_files(res, maps, out, force))


def cmd_merge(args) -> int:
    params = params_from(args)
    if args.topics and not args.bag:
        raise UsageError("--topics: only with --bag BAG")
    out = check_stem(args.output, "-o")
    y, img = map_paths(out)
    inputs = {args.bag: "--bag"} if args.bag else {q: "map" for p in args.maps for q in map_input_paths(p)}
    check_outputs({y: "-o", img: "-o", overlay_path(y): "-o"}, inputs)  # before the maps are decoded
    if args.bag:
        from .io.bagio import check_outputs_outside

        check_outputs_outside(args.bag, {y: "-o", img: "-o", overlay_path(y): "-o"})
    maps, notes = (bag_inputs(args.bag, args.topics, args.maps, args.center, params) if args.bag
                   else file_inputs(args.maps, args.center, params))
    ensure_output_dir(out.parent, "-o")
    if not args.json:
        for note in notes:
            print(f"note: {note}")
    # two maps: the second searched onto the first, as `merger align FIRST SECOND` does (same checks, same answer)
    merged = merge_inputs(maps, params, notes, args.algorithm)
    res = merged.team
    report_merge(merged, args.json, {"resampled": notes})
    written = write_merge(res, maps, out, args.force and all(m.name in res.top.theta_deg for m in maps))
    if not args.json:
        print("wrote " + ", ".join(map(str, written)) if written else
              f"nothing written (rejected by {RULE_NAMES[res.rule]}; --force writes the best hypothesis)")
    return 0 if res.accepted else 1


def cmd_demo(args) -> int:
    from .grid import FREE_S
    from .synthetic import (
        arc_viewpoints,
        partial_view,
        partial_view_of_grid,
        robot_pose_on_circle,
        room_scene,
        widest_free_point,
        world_to_frame,
    )

    params = params_from(args)
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
    out = check_output_folder(args.output, "-o")
    rng = np.random.default_rng(args.seed)
    names, starts = ["Lyon", "Auckland", "Nevers"], [90.0, 210.0, 330.0]
    outputs = {out / f"{n}{ext}": "-o" for n in names for ext in (".yaml", ".pgm")}
    outputs.update({out / CENTERS_FILE: "-o", out / "merged.yaml": "-o", out / "merged.pgm": "-o",
                    out / "merged_overlay.png": "-o"})
    check_outputs(outputs, {q: "--real" for q in map_input_paths(args.real)} if args.real else {})
    if args.real:
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
        radius = args.radius or min(0.8 * clearance, 1.8)
        source = f"{args.real} (center {center[0]:.2f},{center[1]:.2f}, radius {radius:.2f} m)"

        def view(pose, a):
            g = partial_view_of_grid(world, pose, arc_viewpoints(a, args.arc, radius, center))
            return g, tuple(float(v) for v in world_to_frame(center, pose))
    else:
        scene = room_scene(rng)
        center, radius = scene.center, args.radius or 1.8
        source = "a generated room"

        def view(pose, a):
            return partial_view(scene, pose, arc_viewpoints(a, args.arc, radius), noise=0.002, rng=rng)
    if radius <= 0:
        raise UsageError(f"--radius: expected a positive number of metres, got {radius}")
    ensure_output_dir(out, "-o")
    poses, views, files = [], [], {}
    for name, a in zip(names, starts, strict=True):
        pose = robot_pose_on_circle(a, radius, center, yaw_offset_deg=rng.uniform(-40, 40))
        grid, c = view(pose, a)
        files.update(map_files(grid, out / f"{name}.yaml"))
        views.append((grid, c))
        poses.append(pose)
    # the centers the merger is given: exact, or off by e_k (own generator: the views stay the seed's views)
    errs = np.random.default_rng([args.seed, 1]).uniform(-1, 1, (len(names), 2)) * args.center_error
    maps = [MapInput(n, g, (c[0] + e[0], c[1] + e[1])) for n, (g, c), e in zip(names, views, errs, strict=True)]
    truth = {n: math.degrees(p[2] - poses[0][2]) % 360 for n, p in zip(names, poses, strict=True)}
    # x_0 = ĉ_0 + t*_k + R(θ*_k)(x_k − ĉ_k) with ĉ = c + e: t*_k = R(θ*_k) e_k − e_0
    truth_t = {n: tuple(rotation(truth[n]) @ e - errs[0]) for n, e in zip(names, errs, strict=True)}
    res = merge_team(maps, params)
    report_merge(result_of(res, maps), args.json)
    command = merge_command([out / f"{n}.yaml" for n in names], [m.center for m in maps], out / "remerged",
                            params)
    entries = {n: {"map": f"{n}.yaml", "center": list(m.center), "center_true": [float(c[0]), float(c[1])],
                   "pose_world": [float(p[0]), float(p[1]), math.degrees(p[2]) % 360]}
               for n, m, (_, c), p in zip(names, maps, views, poses, strict=True)}
    files[out / CENTERS_FILE] = centers_yaml(entries, {n: (truth[n], truth_t[n]) for n in names}, command,
                                             note=f"merger demo: views of {source}, seed {args.seed}")
    files.update(merge_files(res, maps, out / "merged", force=False))
    written = [p for p in write_files(files) if p.parent == out and p.stem.startswith("merged")]
    if not args.json:
        print(f"views of {source}")
        print("ground truth: " + ", ".join(f"{n} {truth[n]:.1f}° {_xy(truth_t[n])} m" for n in names[1:])
              + (f"  (centers given off by up to ±{args.center_error:g} m)" if args.center_error else
                 "  (exact centers)"))
        # errors of the chosen order, or (labelled as such) of the best rejected hypothesis
        tag = "" if res.chosen else " of the best (rejected) hypothesis"
        a_err = res.top.angle_errors_deg(truth)
        print(f"angle errors{tag}: " + ", ".join(f"{n} {a_err[n]:.2f}°" for n in names[1:]))
        t_err = {n: math.dist(res.top.translation(n), truth_t[n]) for n in names[1:]}
        print(f"translation errors{tag}: " + ", ".join(f"{n} {t_err[n]:.3f} m" for n in names[1:]))
        print(f"wrote the three local maps, {out / CENTERS_FILE} (centers and ground truth) and "
              f"{', '.join(map(str, written)) or 'no merged map'}")
        print(f"re-merge them: {command}")
    return 0 if res.accepted else 1


def exit_now(code: int) -> None:
    """End the process at once with ``code``: Python's exit would first wait for the merge pool's threads to
    finish the searches they are running (compiled kernels cannot be interrupted). Nothing is lost: every
    output is written whole or not at all."""
    import os

    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


def main(argv=None) -> int:
    try:
        args = build_parser().parse_args(join_negative_xy(sys.argv[1:] if argv is None else list(argv)))
        threads()  # MERGER_THREADS=abc: refused before any work (ValueError), not "every core"
        return {"align": cmd_align, "merge": cmd_merge, "demo": cmd_demo}[args.cmd](args)
    except (UsageError, MapFileError, ValueError) as e:
        print(f"merger: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # e.g. `merger merge ... --json | head`: the reader left, not an error of ours
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at interpreter exit
        return 1
    except OSError as e:  # a file the user named cannot be read or written
        print(f"merger: error: {f'{e.filename}: ' if e.filename else ''}{e.strerror or e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("merger: interrupted", file=sys.stderr)
        if argv is None:  # the program: out now, not after the pool's searches still running (26 s on 4224² maps)
            exit_now(130)
        return 130


if __name__ == "__main__":
    sys.exit(main())
