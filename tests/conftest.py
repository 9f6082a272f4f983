"""Shared fixtures: small hand-made grids and generated scenes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from merger.grid import OccupancyGrid
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


@pytest.fixture(scope="session")
def team_views():
    return three_views(3)
