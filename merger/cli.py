"""Command line: ``merger align``, ``merger merge`` and ``merger demo``.

A user's mistake (bad file, bad argument) prints one line ``merger: error: ...`` and exits with 2.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from . import align
from .mapio import MapFileError, ensure_output_dir, load_map, save_map, save_overlay
from .search import SEARCH_METHODS
from .similarity import MEASURES
from .team import MapInput, MergeParams, merge_team
from .transform import canvas, paste, warp_grid
from .verify import verify


class UsageError(Exception):
    pass


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


def add_merge_options(p: argparse.ArgumentParser) -> None:
    d = MergeParams()
    p.add_argument("--roi", type=float, default=d.roi_m, metavar="M",
                   help=f"side of the square region of interest, metres (default {d.roi_m})")
    p.add_argument("--measure", choices=MEASURES, default=d.measure)
    p.add_argument("--method", choices=sorted(SEARCH_METHODS), default=d.method)
    p.add_argument("--nu-min", type=float, default=d.nu_min, help=f"verification threshold (default {d.nu_min})")
    p.add_argument("--min-support", type=int, default=d.min_support,
                   help=f"minimum agr̃+dis on whole maps (default {d.min_support})")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="merger", description="Merge occupancy grid maps of robots sharing a common center.")
    sub = p.add_subparsers(dest="cmd", required=True, parser_class=_Parser)
    a = sub.add_parser("align", help="find the rotation of MOVING onto REF about the common center")
    a.add_argument("ref", type=Path, help="reference map (map_server YAML)")
    a.add_argument("moving", type=Path, help="moving map (map_server YAML)")
    a.add_argument("--center", required=True, help="common center X,Y in REF's frame (and MOVING's)")
    a.add_argument("--center-moving", help="common center X,Y in MOVING's frame, when it differs")
    add_merge_options(a)
    m = sub.add_parser("merge", help="merge N ≥ 2 maps in all orders and write the verified result")
    m.add_argument("maps", type=Path, nargs="+", help="maps (map_server YAML); results in the first one's frame")
    m.add_argument("--center", action="append", required=True,
                   help="common center X,Y: once for all maps, or once per map in order")
    m.add_argument("-o", "--output", type=Path, required=True, help="output stem: writes OUT.yaml/.pgm and OUT_overlay.png")
    m.add_argument("--force", action="store_true", help="write the best hypothesis even if verification rejects it")
    add_merge_options(m)
    d = sub.add_parser("demo", help="three robots' partial maps of a generated scene (or of a saved map, "
                                     "--real), saved and merged")
    d.add_argument("-o", "--output", type=Path, default=Path("out/merger-demo"), help="output folder")
    d.add_argument("--seed", type=int, default=7)
    d.add_argument("--arc", type=float, default=30.0, help="each robot's displacement ±φ in degrees")
    d.add_argument("--real", type=Path, metavar="MAP.yaml",
                   help="cut the robots' views out of this saved map (ROS map_server) instead of a generated "
                        "scene: rays marched through it from the robots' arcs, re-rasterized in each robot's frame")
    d.add_argument("--real-center", metavar="X,Y", help="with --real: the common center in the map's frame "
                   "(default: the free point farthest from any obstacle)")
    d.add_argument("--radius", type=float, help="robots' circle radius in metres (default 1.8; with --real: "
                   "0.8 × the center's clearance, at most 1.8)")
    add_merge_options(d)
    return p


def params_from(args) -> MergeParams:
    if not args.roi > 0:
        raise UsageError(f"--roi: expected a positive number of metres, got {args.roi}")
    return MergeParams(roi_m=args.roi, measure=args.measure, method=args.method, nu_min=args.nu_min,
                       min_support=args.min_support)


def cmd_align(args) -> int:
    params = params_from(args)
    c_ref = parse_xy(args.center, "--center")
    c_mov = parse_xy(args.center_moving, "--center-moving") if args.center_moving else c_ref
    ref, mov = load_map(args.ref), load_map(args.moving)
    al = align(ref, mov, center_ref=c_ref, center_moving=c_mov, roi_m=params.roi_m, measure=params.measure,
               method=params.method)
    cv = canvas(ref, [(mov, al.theta_deg, c_mov)], c_ref)
    v = verify(paste(ref, cv).states, warp_grid(mov, al.theta_deg, c_mov, c_ref, cv).states,
               nu_min=params.nu_min, min_support=params.min_support)
    out = {**al.to_dict(), "ref": str(args.ref), "moving": str(args.moving), "center_ref": list(c_ref),
           "center_moving": list(c_mov), "verification": {"nu": v.nu, "agree": v.counts.agree,
                                                         "disagree": v.counts.disagree, "support": v.support,
                                                         "nu_min": params.nu_min,
                                                         "min_support": params.min_support,
                                                         "accepted": v.passed, "reason": v.reason}}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"theta      {al.theta_deg:8.1f} deg   (x_ref = c_ref + R(theta)(x_moving - c_moving))")
        print(f"score      {al.score:8.3f}       ({al.measure} on the {params.roi_m:g} m ROI; "
              f"agree {al.counts.agree}, disagree {al.counts.disagree})")
        print(f"runner-up  {al.runner_up_deg:8.1f} deg   score {al.runner_up_score:.3f}")
        verdict = "ACCEPTED" if v.passed else f"REJECTED ({v.reason})"
        print(f"verify     ν = {v.nu:.3f} on whole maps, support {v.support}: {verdict}")
    return 0 if v.passed else 1


def merge_inputs(paths: list[Path], centers: list[str]) -> list[MapInput]:
    if len(paths) < 2:
        raise UsageError("merge: expected at least two maps")
    if len(centers) not in (1, len(paths)):
        raise UsageError(f"--center: expected once or once per map ({len(paths)}), got {len(centers)}")
    cs = [parse_xy(c, "--center") for c in centers] * (len(paths) if len(centers) == 1 else 1)
    return [MapInput(p.stem, load_map(p), c) for p, c in zip(paths, cs, strict=True)]


def report_merge(res, as_json: bool) -> None:
    if as_json:
        print(json.dumps(res.to_dict()))
        return
    for o in res.orders:
        angles = ", ".join(f"{k} {v:.1f}°" for k, v in o.theta_deg.items() if k != res.frame)
        nus = ", ".join(f"{k} {v:.3f}" for k, v in o.nu.items())
        mark = "accepted" if o.accepted else f"rejected: {o.reason}"
        star = "*" if o is res.chosen else " "
        print(f"{star} order {'→'.join(o.order):<32} {angles:<30} ν: {nus}  [{mark}]")
    print(f"merge cycle {res.wall_ms:.0f} ms; {'chosen: ' + '→'.join(res.chosen.order) if res.chosen else 'no verified merge'}")


def write_merge(res, maps: list[MapInput], out: Path, force: bool) -> list[Path]:
    from .superpose import fuse
    from .team import fused_layers

    if res.accepted:
        merged, layers = res.merged, [res.layers[m.name] for m in maps]
    elif force:
        layers = fused_layers(maps, res.top.theta_deg)
        merged = type(layers[0])(fuse([g.states for g in layers]), layers[0].resolution, layers[0].origin)
    else:
        return []
    y, img = save_map(merged, out)
    png = save_overlay(layers, [m.name for m in maps], y.with_name(y.stem + "_overlay.png"))
    return [y, img, png]


def cmd_merge(args) -> int:
    params = params_from(args)
    maps = merge_inputs(args.maps, args.center)
    ensure_output_dir(args.output.parent, "-o")
    res = merge_team(maps, params)
    report_merge(res, args.json)
    written = write_merge(res, maps, args.output, args.force)
    if not args.json:
        print("wrote " + ", ".join(map(str, written)) if written else
              "nothing written (no order passed verification; --force writes the best hypothesis)")
    return 0 if res.accepted else 1


def cmd_demo(args) -> int:
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
    rng = np.random.default_rng(args.seed)
    names, starts = ["Lyon", "Auckland", "Nevers"], [90.0, 210.0, 330.0]
    if args.real:
        world = load_map(args.real)
        free_c, clearance = widest_free_point(world)
        center = parse_xy(args.real_center, "--real-center") if args.real_center else free_c
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
    out = args.output
    ensure_output_dir(out, "-o")
    maps, poses = [], []
    for name, a in zip(names, starts, strict=True):
        pose = robot_pose_on_circle(a, radius, center, yaw_offset_deg=rng.uniform(-40, 40))
        grid, c = view(pose, a)
        save_map(grid, out / f"{name}.yaml")
        maps.append(MapInput(name, grid, c))
        poses.append(pose)
    truth = {n: math.degrees(p[2] - poses[0][2]) % 360 for n, p in zip(names, poses, strict=True)}
    res = merge_team(maps, params)
    report_merge(res, args.json)
    written = write_merge(res, maps, out / "merged", force=False)
    if not args.json:
        print(f"views of {source}")
        print("ground truth: " + ", ".join(f"{n} {truth[n]:.1f}°" for n in names[1:]))
        if res.chosen:
            errs = res.chosen.angle_errors_deg(truth)
            print("angle errors: " + ", ".join(f"{n} {errs[n]:.2f}°" for n in names[1:]))
        print(f"wrote the three local maps and {', '.join(map(str, written)) or 'no merged map'} under {out}")
    return 0 if res.accepted else 1


def main(argv=None) -> int:
    try:
        args = build_parser().parse_args(argv)
        return {"align": cmd_align, "merge": cmd_merge, "demo": cmd_demo}[args.cmd](args)
    except (UsageError, MapFileError, ValueError) as e:
        print(f"merger: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:  # a file the user named cannot be read or written
        print(f"merger: error: {e.filename or ''}: {e.strerror or e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("merger: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
