"""How circsim's values become rerun entities: frames, colours, grids, the default blueprint.

The contract: pure functions from our values (poses, grids, scenarios) to rerun archetypes and plain
arrays, used by the recorder (:mod:`circsim.record.rerun`); nothing here logs or holds state. Frames: a
pose is (x, y, yaw) in the world frame W, a robot's map frame M_i is its start pose (DESIGN.md);
:func:`to_frame` and :func:`from_frame` convert points between them. Maps are cropped to their known
cells plus :data:`CROP_MARGIN_CELLS` (:func:`known_window`), and logged ``np.flipud``-ed (rerun draws a
GridMap's first row at its max-y edge). The overlay uses the thesis's colours (:mod:`merger.io.overlay`).
"""

from __future__ import annotations

import functools
import itertools
import math
import re

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from merger.grid import known_bounds
from merger.io.overlay import overlay_rgb

CROP_MARGIN_CELLS = 20  # logged maps and overlays: known cells plus 1 m at 5 cm
GREY = (150, 150, 150)




# --- blueprint ---------------------------------------------------------------------------------------
def default_blueprint(names, center_world, centers_given) -> rrb.Blueprint:
    """World (top-down) with robots and scans, the local maps, the merged maps and overlays, plots, events."""
    cx, cy = center_world
    parts = [entity_part(n) for n in names]
    robots = [(n, entity_part(n)) for n in names]
    world = rrb.Spatial3DView(
        name="World (top-down, y up)", origin="/world",
        # the maps have views of their own: drawn here (opaque in the 0.41 web viewer, whatever the
        # opacity) they hid the world under three rotated rectangles of unknown cells
        # center_given is drawn there as centers/given (in W), once
        contents=["+ $origin/**", *[f"- /world/robots/{p}/map/{m}" for p in parts
                                    for m in ("merged", "local", "center_given")]],
        eye_controls=top_down(cx, cy, 11.0))

    def map_view(n, p, what, title):
        gx, gy = centers_given[n]
        return rrb.Spatial3DView(
            name=f"{n}: {title}", origin=f"/world/robots/{p}/map",
            contents=[f"$origin/{what}", "$origin/slam_pose", "$origin/center_given", f"/world/robots/{p}/scan"],
            eye_controls=top_down(gx, gy, 11.0))

    local_maps = rrb.Horizontal(*[map_view(n, p, "local", "local map") for n, p in robots])
    merged = rrb.Vertical(*[rrb.Tabs(
        rrb.Spatial2DView(name=f"{n}: overlay of aligned maps", origin=f"/merge/{p}"),
        map_view(n, p, "merged", "merged map"), name=n) for n, p in robots])

    def plots(n, p):
        ts = [rrb.TimeSeriesView(name=f"{n}: {title}", origin=f"/plots/{p}/{what}")
              for what, title in (("omega", "ω̃ of each alignment step, every order"),
                                  ("nu", "ν of the top hypothesis"), ("support", "support (agr̃ + dis)"),
                                  ("angle_error_deg", "accepted angle error vs truth (°)"),
                                  ("translation_error_m", "accepted translation error vs truth (m)"))]
        ts.append(rrb.TimeSeriesView(name=f"{n}: teammates correctly placed", origin=f"/plots/{p}/teammates_placed"))
        ts.append(rrb.TimeSeriesView(name=f"{n}: SLAM pose error (cm, °)", origin=f"/plots/{p}/slam_pose_error"))
        ts.append(rrb.TimeSeriesView(name=f"{n}: merge cycle cost (ms)", origin=f"/plots/{p}/cycle_ms"))
        return rrb.Vertical(*ts, name=n)

    right = rrb.Vertical(rrb.Tabs(*[plots(n, p) for n, p in robots]),
                         rrb.TextLogView(name="Events", origin="/events"), row_shares=[3, 2])
    return rrb.Blueprint(
        rrb.Horizontal(rrb.Vertical(world, local_maps, row_shares=[3, 2]), merged, right, column_shares=[3, 2, 3]),
        rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline="sim_time"))


def top_down(x: float, y: float, height: float) -> rrb.EyeControls3D:
    return rrb.EyeControls3D(position=[x, y, height], look_target=[x, y, 0.0], eye_up=[0.0, 1.0, 0.0])



# --- helpers -------------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=16)
def _overlay_lut(names: tuple[str, ...]) -> np.ndarray:
    """RGB of every combination of cell states (3**N, 3), computed by :func:`merger.io.overlay.overlay_rgb`."""
    combos = np.array(list(itertools.product(range(3), repeat=len(names))), np.uint8)
    return overlay_rgb([combos[:, k, None] for k in range(len(names))], list(names))[:, 0]


def overlay_fast(layers: list[np.ndarray], names: list[str]) -> np.ndarray:
    """Same image as :func:`merger.io.overlay.overlay_rgb` (which it tabulates), ~20x faster for N <= 5 maps.

    A cell's colour depends only on the states of that cell in the N layers, so the 3**N colours are
    computed once by ``overlay_rgb`` itself and looked up.
    """
    if len(names) > 5:
        return overlay_rgb(layers, names)
    code = np.array(layers[0], np.uint8)  # 3**5 = 243 codes fit in uint8
    for states in layers[1:]:
        code *= 3
        code += states
    return np.take(_overlay_lut(tuple(names)), code, axis=0)


def entity_part(name: str) -> str:
    """A robot name as one entity-path part (letters, digits, '-', '_')."""
    return re.sub(r"[^A-Za-z0-9_-]", "_", str(name))


def rr_transform(x: float, y: float, yaw: float) -> rr.Transform3D:
    return rr.Transform3D(translation=[float(x), float(y), 0.0],
                          rotation=rr.RotationAxisAngle(axis=[0.0, 0.0, 1.0], radians=float(yaw)))


def known_window(layers: list[np.ndarray], margin: int = CROP_MARGIN_CELLS) -> tuple[slice, slice]:
    """Rows and columns of the smallest window holding every known cell of ``layers`` (same shape),
    widened by ``margin`` cells and clipped to the grid; the whole grid when nothing is known.

    Logged maps and overlays are cropped to it: a 16 m map of a 7 m room is mostly unknown, which the
    viewer draws opaque, and the overlay's room would be a small patch in a grey image."""
    known = np.zeros(layers[0].shape, bool)
    for states in layers:
        known |= states != 0
    h, w = known.shape
    box = known_bounds(known)
    if box is None:
        return slice(0, h), slice(0, w)
    r0, r1, c0, c1 = box
    return slice(max(r0 - margin, 0), min(r1 + margin, h)), slice(max(c0 - margin, 0), min(c1 + margin, w))


def rr_grid_map(grid, z: float) -> rr.GridMap:
    """A ROS-ordered occupancy grid (row 0 = lowest y) as a GridMap with the rviz colour map, cropped
    to its known cells (:func:`known_window`; the translation is the window's corner)."""
    rs, cs = known_window([grid.states])
    ros = grid.to_ros()[rs, cs]
    data = np.ascontiguousarray(np.flipud(ros))  # GridMap draws its first data row at max y
    x0 = grid.origin[0] + cs.start * grid.resolution
    y0 = grid.origin[1] + rs.start * grid.resolution
    return rr.GridMap(data=data.view(np.uint8).tobytes(),
                      format=rr.components.ImageFormat(width=ros.shape[1], height=ros.shape[0], color_model="L",
                                                       channel_datatype="U8"),
                      cell_size=grid.resolution, translation=[x0, y0, z],
                      colormap=rr.components.Colormap.RvizMap)


def circle_points(cx: float, cy: float, r: float, n: int = 96) -> np.ndarray:
    a = np.linspace(0.0, 2.0 * math.pi, n + 1)
    return np.stack([cx + r * np.cos(a), cy + r * np.sin(a), np.zeros_like(a)], axis=1)


def to_frame(xy, pose) -> tuple[float, float]:
    """World point ``xy`` in the frame of ``pose`` (x, y, yaw)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    dx, dy = xy[0] - pose[0], xy[1] - pose[1]
    return (c * dx + s * dy, -s * dx + c * dy)


def from_frame(xy, pose) -> tuple[float, float]:
    """Point ``xy`` of the frame of ``pose`` (x, y, yaw) in the world frame (inverse of :func:`to_frame`)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return (pose[0] + c * xy[0] - s * xy[1], pose[1] + s * xy[0] + c * xy[1])


def dim_colour(col) -> tuple[int, int, int]:
    return tuple(int(0.5 * v + 0.5 * 255) for v in col)


def split_geometry(sc, geo):
    """Static geometry as line strips: walls (the room, or a map world's cell edges), pillars, and the
    remaining objects."""
    segs = list(sc.world.room.wall_segments())
    if sc.world.map_grid is not None:
        from ..world.mapgeometry import boundary_segments

        g = sc.world.map_grid
        segs += [tuple(s) for s in boundary_segments(g.solid, g.resolution, g.origin).tolist()]
    walls = [np.array([[a, b, 0.0], [c, d, 0.0]]) for a, b, c, d in segs]
    wall_keys = {value_key(s) for s in segs} | {value_key((c, d, a, b)) for a, b, c, d in segs}
    pillar_keys = {value_key((*p.center, p.radius)) for p in sc.world.pillars}
    pillars = [circle_points(p.center[0], p.center[1], p.radius, 48) for p in sc.world.pillars]
    objects = [np.array([[a, b, 0.0], [c, d, 0.0]]) for a, b, c, d in geo.segments
               if value_key((a, b, c, d)) not in wall_keys]
    objects += [circle_points(x, y, r, 24) for x, y, r in geo.circles if value_key((x, y, r)) not in pillar_keys]
    return walls, pillars, objects


def value_key(v) -> tuple:
    return tuple(round(float(x), 6) for x in v)


def scenario_dict(sc) -> dict:
    from ..config.scenario import scenario_to_dict

    return scenario_to_dict(sc)


def json_block(d) -> str:
    """``d`` as a Markdown JSON block, its floats written as in the run's JSON file (:mod:`circsim.record.jsonout`)."""
    from . import jsonout

    return "```json\n" + jsonout.dumps(d, indent=2, default=str) + "\n```\n"
