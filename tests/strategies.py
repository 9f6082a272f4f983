"""Shared generators: small hand-made grids, generated three-robot scenes (:func:`three_views`) and
adversarial search problems (tests and benchmarks/agree_search.py import them; never the reverse).

Kinds (``adversarial_problem``): random ternary grids; a map against its own rotation shifted by one
cell (near-ties, plateaus); walls where the window's edge puts them; near-empty maps; maps of two
resolutions — each with centers anywhere, on cell centres or on cell corners (ROIs that are not plain
blocks), rotation only or with a window.
"""

from __future__ import annotations

import math

import numpy as np

from merger.grid import FREE_S, OCCUPIED_S, OccupancyGrid
from merger.search import RotationProblem
from merger.synthetic import arc_viewpoints, partial_view, robot_pose_on_circle, room_scene

U, F, O = 0, 1, 2  # state codes


def grid(rows, res=0.05, origin=(0.0, 0.0)):
    """An OccupancyGrid from rows of state codes, first row = lowest y."""
    return OccupancyGrid(np.array(rows, np.uint8), res, origin)


def three_views(seed: int, *, arc=30.0, radius=1.8, noise=0.002, yaw_spread=40.0, **scene_kw):
    """Scene + three robots' partial maps (names Lyon, Auckland, Nevers) and true rotations onto Lyon."""
    rng = np.random.default_rng(seed)
    scene = room_scene(rng, **scene_kw)
    names, starts = ["Lyon", "Auckland", "Nevers"], [90.0, 210.0, 330.0]
    maps, poses = [], []
    for a in starts:
        pose = robot_pose_on_circle(a, radius, yaw_offset_deg=rng.uniform(-yaw_spread, yaw_spread))
        g, c = partial_view(scene, pose, arc_viewpoints(a, arc, radius), noise=noise, rng=rng)
        maps.append((g, c))
        poses.append(pose)
    truth = {n: math.degrees(p[2] - poses[0][2]) % 360 for n, p in zip(names, poses, strict=True)}
    return scene, names, maps, truth


def random_grid(rng, side: int, res: float = 0.05, p=None) -> OccupancyGrid:
    p = rng.dirichlet([1, 1, 1]) if p is None else p
    st_ = rng.choice(3, size=(side, side), p=p).astype(np.uint8)
    org = (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)))
    return OccupancyGrid(st_, res, org)


def random_point(rng, g: OccupancyGrid, mode: str):
    """A point inside ``g``: anywhere, on a cell centre or on a cell corner."""
    col = int(rng.integers(g.width // 4, 3 * g.width // 4))
    row = int(rng.integers(g.height // 4, 3 * g.height // 4))
    if mode == "centre":
        return (g.origin[0] + (col + 0.5) * g.resolution, g.origin[1] + (row + 0.5) * g.resolution)
    if mode == "corner":
        return (g.origin[0] + col * g.resolution, g.origin[1] + row * g.resolution)
    return (g.origin[0] + float(rng.uniform(col, col + 1)) * g.resolution,
            g.origin[1] + float(rng.uniform(row, row + 1)) * g.resolution)


def adversarial_problem(seed: int, measure: str, window: bool) -> RotationProblem:
    """One of several generated problem kinds (see the module documentation), small enough for the spec."""
    rng = np.random.default_rng(seed)
    kind = ("noise", "rotated_copy", "edge_wall", "near_empty", "two_res")[seed % 5]
    mode = ("any", "centre", "corner")[(seed // 5) % 3]
    side = int(rng.integers(16, 40))
    g = random_grid(rng, side)
    h = random_grid(rng, side)
    if kind == "rotated_copy":  # a map against its own rotation, shifted by one cell: near-ties, plateaus
        k = int(rng.integers(0, 4))
        h = OccupancyGrid(np.roll(np.rot90(g.states, k), 1, axis=int(rng.integers(0, 2))), g.resolution, g.origin)
    elif kind == "edge_wall":  # free maps with walls where the window's edge puts them
        st_ = np.full((side, side), FREE_S, np.uint8)
        st_[:, side // 2 + 3] = OCCUPIED_S
        st_[side // 2 - 2, :] = OCCUPIED_S
        g = OccupancyGrid(st_, 0.05, g.origin)
        h = OccupancyGrid(np.rot90(st_).copy(), 0.05, h.origin)
    elif kind == "near_empty":
        st_ = np.zeros((side, side), np.uint8)
        st_[rng.random(st_.shape) < 0.3] = FREE_S
        for _ in range(int(rng.integers(0, 4))):
            st_[rng.integers(0, side), rng.integers(0, side)] = OCCUPIED_S
        h = OccupancyGrid(st_, 0.05, h.origin)
    elif kind == "two_res":
        h = random_grid(rng, side // 2 + 4, res=0.1)
    cr, cm = random_point(rng, g, mode), random_point(rng, h, mode)
    roi = float(rng.choice([0.6, 0.75, 0.8, 1.0]))
    w = float(rng.choice([0.05, 0.1, 0.15])) if window else 0.0
    floor = int(rng.choice([0, 0, 3, 25, 120]))  # the support floor: off, or biting some placements
    return RotationProblem(g, h, cr, cm, roi, measure, w, min_support=floor)


def saved_views(folder, seed: int = 5):
    """:func:`three_views` saved as ROS map_server files in ``folder``: (paths of their YAML files, centers
    (x, y) per map, true rotations onto Lyon) — the command lines' inputs."""
    from merger.io.mapio import save_map

    _, names, maps, truth = three_views(seed)
    paths = [save_map(g, folder / f"{n}.yaml")[0] for n, (g, _) in zip(names, maps, strict=True)]
    return paths, [c for _, c in maps], truth
