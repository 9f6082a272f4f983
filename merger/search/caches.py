"""The search's caches: the prepared searcher of the last problems, the moving maps' own arrays, the
reference geometries' lattice tables, and :func:`clear_all`.

A merge cycle asks several questions of one problem object (the answer, then perhaps the runner-up,
the guard beyond the window, a rival's values): they share one :class:`merger.search.engine.Searcher`
(its lattice tables and the moving ROIs it computed), kept here by the problem's identity for the
last ``MAX_ENTRIES`` problems. Values never depend on the cache: a searcher is a pure function of its
problem. Numba's on-disk cache of compiled kernels is separate (``NUMBA_CACHE_DIR``).
"""

from __future__ import annotations

import threading
import weakref
from collections import OrderedDict

MAX_ENTRIES = 8
_LOCK = threading.Lock()
_SEARCHERS: OrderedDict = OrderedDict()


def searcher(problem, k, factory):
    """The searcher of ``problem`` (window ``k`` cells; None: the problem's own), built by ``factory``."""
    key = (id(problem), k)
    with _LOCK:
        hit = _SEARCHERS.get(key)
        if hit is not None and hit[0] is problem:
            _SEARCHERS.move_to_end(key)
            return hit[1]
    s = factory(problem, k)
    with _LOCK:
        _SEARCHERS[key] = (problem, s)
        while len(_SEARCHERS) > MAX_ENTRIES:
            _SEARCHERS.popitem(last=False)
    return s


MOVING_ENTRIES = 16
_MOVING: OrderedDict = OrderedDict()


def moving_side(grid, key: tuple, factory):
    """Arrays that depend on the moving map alone (and ``key``: its center, the ROI), kept for the
    last ``MOVING_ENTRIES`` maps: a map is the moving map of several searches of a merge cycle. The grid
    object itself is held with its entry, so an id is never mistaken for another map's."""
    k = (id(grid),) + key
    with _LOCK:
        hit = _MOVING.get(k)
        if hit is not None and hit[0] is grid:
            _MOVING.move_to_end(k)
            return hit[1]
    value = factory()
    with _LOCK:
        _MOVING[k] = (grid, value)
        while len(_MOVING) > MOVING_ENTRIES:
            _MOVING.popitem(last=False)
    return value


GEOMETRY_ENTRIES = 32
_GEOMETRY: OrderedDict = OrderedDict()


def geometry(key: tuple, factory):
    """Arrays that depend on a reference map's geometry alone (``key``: its origin, resolution, size, the
    center, the ROI and the window), kept for the last ``GEOMETRY_ENTRIES`` geometries: a robot's map
    keeps its frame and its center while it grows, so every version of it is prepared from the same."""
    with _LOCK:
        hit = _GEOMETRY.get(key)
        if hit is not None:
            _GEOMETRY.move_to_end(key)
            return hit
    value = factory()
    with _LOCK:
        _GEOMETRY[key] = value
        while len(_GEOMETRY) > GEOMETRY_ENTRIES:
            _GEOMETRY.popitem(last=False)
    return value


# the fast search's frontier per problem object, for as long as the problem lives (a runner-up search of
# the same problem starts from it: merger.search.engine.exact_runner_up); keyed by the object itself, so
# what a later search finds never depends on what else was cached meanwhile
_FRONTIERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def keep_frontier(problem, frontier) -> None:
    with _LOCK:
        _FRONTIERS[problem] = frontier


def frontier(problem):
    """The frontier the fast search of ``problem`` left (None if it has not run)."""
    with _LOCK:
        return _FRONTIERS.get(problem)


def clear_all() -> None:
    """Forget every cached searcher, moving-map array, reference geometry and search frontier (memory between independent
    runs, e.g. sweep workers)."""
    with _LOCK:
        _FRONTIERS.clear()
        _SEARCHERS.clear()
        _MOVING.clear()
        _GEOMETRY.clear()
