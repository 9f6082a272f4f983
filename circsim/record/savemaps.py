"""``circsim run --save-maps DIR``: the robots' maps as ROS map_server files, for ``merger merge``.

Every robot's last published map (its own frame) is written as ``DIR/<robot>.yaml`` + ``.pgm``, with
``DIR/centers.yaml`` (:func:`merger.io.mapio.centers_yaml`): each map's common center as given to the merger
(with the scenario's center error) and exact, the robot's start pose in the world, the ground truth of
every map onto the first robot's (θ*, t* about the given centers, as the run's metrics judge it) and the
``merger merge`` command that merges the maps with the scenario's merge parameters.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from merger.io.mapio import CENTERS_FILE, centers_yaml, map_files, merge_command

from ..events import Observer
from ..sim import merge_params


class MapSaver(Observer):
    """Observer keeping each robot's last published map, its centers and the run's ground truth, for
    ``circsim run --save-maps DIR`` (written by :meth:`files` after the run, all files or none)."""

    def __init__(self) -> None:
        self.grids: dict = {}
        self.centers: dict = {}
        self.sim = None

    def on_start(self, sim) -> None:
        self.sim = sim

    def on_map_published(self, t, robot, grid, center_given, center_true) -> None:
        self.grids[robot] = grid
        self.centers[robot] = (tuple(map(float, center_given)), tuple(map(float, center_true)))

    def files(self, out: Path) -> dict:
        """``{path: bytes}`` of the maps and ``centers.yaml`` under ``out`` (nothing if no map was
        published): pass it to :func:`merger.io.mapio.write_files`."""
        names = [n for n in self.sim.robot_names if n in self.grids]
        stem = {n: file_stem(n, i) for i, n in enumerate(names)}
        files: dict = {}
        for n in names:
            files.update(map_files(self.grids[n], out / f"{stem[n]}.yaml"))
        if not names:
            return files
        entries = {}
        for n in names:
            given, true = self.centers[n]
            p = self.sim.start_poses[n]
            entries[n] = {"map": f"{stem[n]}.yaml", "center": list(given), "center_true": list(true),
                          "pose_world": [float(p.x), float(p.y), math.degrees(p.yaw) % 360]}
        first = names[0]
        truth = {n: (self.sim.truth_deg[first][n], self.sim.truth_translation_m[first][n]) for n in names}
        sc = self.sim.scenario
        command = merge_command([out / f"{stem[n]}.yaml" for n in names], [self.centers[n][0] for n in names],
                                out / "merged", merge_params(sc))
        files[out / CENTERS_FILE] = centers_yaml(
            entries, truth, command, note=f"circsim run {sc.name} seed {sc.seed}: each robot's last published "
                                          f"map at {self.sim.result.sim_s:.1f} s simulated")
        return files


def file_stem(robot: str, index: int) -> str:
    """A file name for a robot's map: its name, with anything but letters, digits, '-', '_' and '.'
    replaced (a name is not a path); numbered when nothing is left."""
    s = re.sub(r"[^\w.-]", "_", robot).strip(".")
    return s or f"robot{index}"
