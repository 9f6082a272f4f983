"""The maps of a merge as a caller gives them: file paths (map_server YAML) or grids, read and named.

:func:`read_inputs` turns each path into an :class:`~merger.grid.OccupancyGrid` (:func:`.mapio.load_map`)
and names every map: a path by its file stem (``Lyon.yaml`` → ``Lyon``), or, when stems repeat (map_saver's
``map.yaml`` three times), by as many trailing path parts as make them distinct (``r1/map``, ``r2/map``);
a grid by ``map<i>`` (1-based). A file that cannot be read, or one file given twice, is a
:class:`~merger.inputs.MergeInputError` naming it (the same words as a :class:`.mapread.MapFileError`).
"""

from __future__ import annotations

import os
from pathlib import Path

from ..grid import OccupancyGrid
from ..inputs import MergeInputError
from .mapio import load_map
from .mapread import MapFileError


def map_names(paths: list[Path]) -> list[str]:
    """One distinct name per map file (see the module's docstring); the same file twice is refused."""
    resolved = [Path(p).resolve() for p in paths]
    for i, r in enumerate(resolved):
        if r in resolved[:i]:
            raise MergeInputError("maps", f": {paths[i]} is given twice (expected distinct maps)")
    parts = [p.with_suffix("").parts for p in resolved]
    for k in range(1, max(map(len, parts)) + 1):
        names = ["/".join(q[-k:]) for q in parts]
        if len(set(names)) == len(names):
            return names
    raise MergeInputError("maps", ": cannot name the maps distinctly")  # pragma: no cover - resolved paths differ


def read_inputs(maps, names=None) -> tuple[list[OccupancyGrid], list[str], list[str]]:
    """(grids, names, labels) of ``maps``: paths read, grids as given; ``labels`` name each map in messages
    (its path, or ``maps[i]``). ``names`` (optional): the caller's names, distinct (then one file may be
    given twice: ``merger align MAP MAP``)."""
    maps = list(maps)
    is_path = [isinstance(m, (str, os.PathLike)) for m in maps]
    for i, m in enumerate(maps):
        if not is_path[i] and not isinstance(m, OccupancyGrid):
            raise MergeInputError(f"maps[{i}]", f": expected a map file path or an OccupancyGrid, got "
                                  f"{type(m).__name__}")
    if names is None:
        paths = [Path(m) for m, p in zip(maps, is_path, strict=True) if p]
        stems = iter(map_names(paths)) if paths else iter(())
        names = [next(stems) if p else f"map{i + 1}" for i, p in enumerate(is_path)]
    else:
        names = [str(n) for n in names]
        if len(names) != len(maps) or len(set(names)) != len(names):
            raise MergeInputError("names", f": expected {len(maps)} distinct names, one per map, got {names!r}")
    grids = []
    for m, p in zip(maps, is_path, strict=True):
        if not p:
            grids.append(m)
            continue
        try:
            grids.append(load_map(m))
        except MapFileError as e:
            raise MergeInputError("", str(e)) from None
        except OSError as e:
            raise MergeInputError("", f"{e.filename or m}: {e.strerror or e}") from None
    labels = [str(m) if p else f"maps[{i}]" for i, (m, p) in enumerate(zip(maps, is_path, strict=True))]
    return grids, names, labels
