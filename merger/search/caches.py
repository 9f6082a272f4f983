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
MOVING_ENTRIES = 16
_MOVING: OrderedDict = OrderedDict()
GEOMETRY_ENTRIES = 32
_GEOMETRY: OrderedDict = OrderedDict()


def _kept(store: OrderedDict, key, owner, factory, limit: int):
    """``store[key]``'s value if it was made for ``owner`` (the object itself is held with the entry, so
    an id is never mistaken for another's), else ``factory()`` kept there; the last ``limit`` entries."""
    with _LOCK:
        hit = store.get(key)
        if hit is not None and hit[0] is owner:
            store.move_to_end(key)
            return hit[1]
    value = factory()
    with _LOCK:
        store[key] = (owner, value)
        while len(store) > limit:
            store.popitem(last=False)
    return value


def searcher(problem, k, factory):
    """The searcher of ``problem`` (window ``k`` cells; None: the problem's own), built by ``factory``."""
    return _kept(_SEARCHERS, (id(problem), k), problem, lambda: factory(problem, k), MAX_ENTRIES)


def moving_side(grid, key: tuple, factory):
    """Arrays that depend on the moving map alone (and ``key``: its center, the ROI), kept for the
    last ``MOVING_ENTRIES`` maps: a map is the moving map of several searches of a merge cycle."""
    return _kept(_MOVING, (id(grid),) + key, grid, factory, MOVING_ENTRIES)


def geometry(key: tuple, factory):
    """Arrays that depend on a reference map's geometry alone (``key``: its origin, resolution, size, the
    center, the ROI and the window), kept for the last ``GEOMETRY_ENTRIES`` geometries: a robot's map
    keeps its frame and its center while it grows, so every version of it is prepared from the same."""
    return _kept(_GEOMETRY, key, None, factory, GEOMETRY_ENTRIES)


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
