"""What the commands print and write: the text (or JSON) of a merge and of an alignment, and the merged
map's files (``OUT.yaml``/``.pgm`` and ``OUT_overlay.png``).

The words are the library's (:mod:`merger.verdict`: the rule that decided and its figures); each map's
pose is the :class:`~merger.pose.Pose` of its frame in the first map's (what a tf needs). The overlay's
title is ASCII (:func:`ascii_text`: OpenCV's fonts have no θ, ν, →).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..io.mapio import map_files, map_paths, overlay_png, write_files
from ..team.params import MapInput
from ..team.verify import no_evidence
from ..transform import rotation
from ..verdict import RULE_NAMES, evidence_text, refusal, rule_of


def xy_text(v) -> str:
    return f"({v[0]:.3f}, {v[1]:.3f})"


def report_align(merged, params, where: dict, notes, as_json: bool) -> None:
    """Print ``merger align``'s answer (a :class:`~merger.api.MergeResult` of the one order REF, MOVING):
    the search's θ and t with what they mean for the centers, its score and runner-up, the verification,
    the verdict and MOVING's pose. ``where``: the inputs as given (paths, centers, notes)."""
    res = merged.team
    o = res.top
    al = o.steps[0][1]
    c_ref, c_mov = where["center_ref"], where["center_moving"]
    moving = merged.names[1]
    if not al.has_evidence:
        why = no_evidence(al, params.roi_min_support)
        if as_json:
            print(json.dumps({**al.to_dict(), **where, "verdict": "no_evidence", "rule": "no_evidence",
                              "reason": why}))
        else:
            print(f"no evidence  {why}")
        return
    v = next(iter(o.checks.values()))
    out = {**al.to_dict(), **where, "verdict": "accepted" if res.accepted else "rejected", "rule": res.rule,
           "reason": res.reason,
           "verification": {**v.to_dict(), "nu_min": params.nu_min, "min_support": params.min_support,
                            "accepted": v.passed}, "decided_by": merged.rule,
           "pose": merged.poses[moving].to_dict(), "search_pose": merged.search_poses[moving].to_dict()}
    if res.chosen is not None and res.chosen.search_theta_deg:  # accepted by the contrast rule: refined
        out["refined_placement"] = {"theta_deg": res.chosen.theta_deg[moving],
                                    "translation_m": list(res.chosen.translation(moving))}
    if as_json:
        print(json.dumps(out))
        return
    for note in notes:
        print(f"note         {note}")
    tx, ty = al.translation_m
    c_target = (c_ref[0] + tx, c_ref[1] + ty)  # where MOVING's center lands in REF's frame
    # REF's center in MOVING's frame implied by (θ, t): x_ref = c_ref + R(θ)(x_moving − c_mov')
    d = rotation(-al.theta_deg) @ np.array([tx, ty])
    c_mov_fix = (c_mov[0] - d[0], c_mov[1] - d[1])
    how = f"window ±{params.window_m:g} m, " if params.window_m > 0 else "rotation only (--window 0), "
    how += (f"refined from the grid answer {al.theta_grid_deg:.1f} deg, {xy_text(al.translation_grid_m)} m"
            if al.refined else "grid answer: 0.1 deg, whole cells")
    print(f"theta        {al.theta_deg:9.2f} deg   (x_ref = c_ref + t + R(theta)(x_moving - c_moving))")
    print(f"translation  {tx:+.3f}, {ty:+.3f} m  ({how})")
    print(f"             MOVING's center lands at {xy_text(c_target)} in REF's frame; given REF center "
          f"{xy_text(c_ref)}: correction ({tx:+.3f}, {ty:+.3f}) m")
    print(f"             equivalently, with REF's center exact, MOVING's center is {xy_text(c_mov_fix)} "
          f"in its own frame (given {xy_text(c_mov)})")
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
        print(f"refined      {r['theta_deg']:9.2f} deg, t {xy_text(r['translation_m'])} m   (the placement refined on the "
              f"whole maps, where `merger merge` draws the merged map)")
    p = merged.poses[moving]
    print(f"pose         x {p.x:+.3f} m, y {p.y:+.3f} m, yaw {p.yaw_deg:.2f} deg   (MOVING's frame in REF's: "
          "p_ref = R(yaw) p_moving + (x, y)" + ("" if res.accepted else "; rejected") + ")")


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
    from ..team.frames import fused_layers
    from ..team.superpose import fuse_grids

    if res.accepted:
        merged, layers = res.merged, [res.layers[m.name] for m in maps]
    elif force:
        layers = fused_layers(maps, res.top.theta_deg, res.top.translation_m)
        merged = fuse_grids(layers)
    else:
        return {}
    files = map_files(merged, out)
    files[overlay_path(map_paths(out)[0])] = overlay_png(layers, [m.name for m in maps],
                                                             title=overlay_title(res))
    return files


def overlay_path(yaml_path: Path) -> Path:
    """OUT_overlay.png beside OUT.yaml (the stem keeps its dots)."""
    return yaml_path.with_name(yaml_path.name.removesuffix(".yaml") + "_overlay.png")


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

