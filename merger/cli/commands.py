"""The three commands, each a short function over the library's API: ``merger align`` (one pair, every
check of a merge), ``merger merge`` (N maps from files or a ROS 2 bag) and ``merger demo`` (three robots'
views of a generated room or a saved map, saved and merged, with the ground truth).

Each takes the parsed arguments with ``args.params``, the merge settings :func:`merger.cli.main` checked
(:func:`merger.cli.params_from`), and returns the exit code: 0 accepted, 1 refused. Outputs are checked
before any map is decoded and written whole or not at all (:func:`merger.io.mapio.write_files`).
"""

from __future__ import annotations

import math
from dataclasses import asdict

import numpy as np

from ..api import merge_inputs, prepare, result_of
from ..io.mapio import (
    CENTERS_FILE,
    centers_yaml,
    check_outputs,
    ensure_output_dir,
    map_files,
    map_input_paths,
    map_paths,
    merge_command,
    write_files,
)
from ..team.orders import MapInput, merge_team
from ..transform import rotation
from ..verdict import RULE_NAMES
from .checks import (
    bag_inputs,
    check_demo_options,
    check_output_folder,
    check_stem,
    file_inputs,
    options_named,
    pair_names,
    parse_xy,
    real_scene,
)
from .parser import UsageError
from .report import merge_files, overlay_path, report_align, report_merge, write_merge, xy_text


def cmd_align(args) -> int:
    """MOVING searched onto REF and judged by every check of ``merger merge`` (the one order (0, 1) of
    :func:`merge_team`: the ambiguity rule's runner-up, the verification, the guard beyond the window):
    align accepts exactly what merge would accept of that search."""
    params = args.params
    c_ref = parse_xy(args.center, "--center")
    c_mov = parse_xy(args.center_moving, "--center-moving") if args.center_moving else c_ref
    names = pair_names(args.ref, args.moving)
    moving_key = "--center-moving" if args.center_moving else "--center"
    with options_named({"centers[0]": "--center", "centers[1]": moving_key}):
        maps, params, notes = prepare([args.ref, args.moving], [c_ref, c_mov], names=names, **asdict(params))
    merged = merge_inputs(maps, params, notes)
    where = {"ref": str(args.ref), "moving": str(args.moving), "center_ref": list(c_ref),
             "center_moving": list(c_mov), "resampled": notes}
    report_align(merged, params, where, notes, args.json)
    return 0 if merged.team.accepted and merged.team.top.steps[0][1].has_evidence else 1


def cmd_merge(args) -> int:
    params = args.params
    if args.topics and not args.bag:
        raise UsageError("--topics: only with --bag BAG")
    out = check_stem(args.output, "-o")
    y, img = map_paths(out)
    inputs = {args.bag: "--bag"} if args.bag else {q: "map" for p in args.maps for q in map_input_paths(p)}
    check_outputs({y: "-o", img: "-o", overlay_path(y): "-o"}, inputs)  # before the maps are decoded
    if args.bag:
        from ..io.bagio import check_outputs_outside

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
    from ..synthetic import (
        arc_viewpoints,
        partial_view,
        partial_view_of_grid,
        robot_pose_on_circle,
        room_scene,
        world_to_frame,
    )

    params = args.params
    check_demo_options(args, params)
    out = check_output_folder(args.output, "-o")
    rng = np.random.default_rng(args.seed)
    names, starts = ["Lyon", "Auckland", "Nevers"], [90.0, 210.0, 330.0]
    outputs = {out / f"{n}{ext}": "-o" for n in names for ext in (".yaml", ".pgm")}
    outputs.update({out / CENTERS_FILE: "-o", out / "merged.yaml": "-o", out / "merged.pgm": "-o",
                    out / "merged_overlay.png": "-o"})
    check_outputs(outputs, {q: "--real" for q in map_input_paths(args.real)} if args.real else {})
    if args.real:
        world, center, clearance = real_scene(args, params)
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
        print("ground truth: " + ", ".join(f"{n} {truth[n]:.1f}° {xy_text(truth_t[n])} m" for n in names[1:])
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


