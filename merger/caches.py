"""The merger's caches: a small thread-safe LRU cache bounded in entries and in bytes, a content key for
arrays, and :func:`clear_all` — the one way to empty every cache the merger keeps between calls.

The merger keeps a few derived arrays between searches (polar spectra of a map, sample indices) so
that an unchanged map is not processed again in the next merge cycle. A simulation runs for minutes
and every published map is new, so every such cache must forget: :class:`BoundedCache` evicts the
least recently used entries once it holds more than ``max_entries`` values or ``max_bytes`` bytes of
numpy arrays. Keys are cheap (geometry and a content digest, :func:`array_digest`), never a scan.

No answer depends on a cache (a cached value is a pure function of its key): :func:`clear_all` only
returns memory, e.g. between the independent runs of a sweep worker. Callers outside the merger clear
caches through it.

The search's own caches (below :class:`BoundedCache`): a merge cycle asks several questions of one
problem object (the answer, then perhaps the runner-up, the guard beyond the window, a rival's values):
they share one :class:`merger.search.searcher.Searcher` (its lattice tables and the moving ROIs it
computed), kept by the problem's identity for the last ``MAX_ENTRIES`` problems; arrays of a moving
map alone, of a reference map alone and of a reference geometry alone are kept likewise. Numba's on-disk cache of compiled
kernels is separate (``NUMBA_CACHE_DIR``).
"""

from __future__ import annotations

import hashlib
import threading
import weakref
from collections import OrderedDict

import numpy as np


def array_digest(a: np.ndarray) -> bytes:
    """A 16-byte content key of an array: its bytes, shape and dtype (BLAKE2b)."""
    a = np.ascontiguousarray(a)
    h = hashlib.blake2b(a.data, digest_size=16)
    h.update(repr((a.shape, a.dtype.str)).encode())
    return h.digest()


def _nbytes(value) -> int:
    if isinstance(value, np.ndarray):
        return int(value.nbytes)
    if isinstance(value, (tuple, list)):
        return sum(_nbytes(v) for v in value)
    return 0


class BoundedCache:
    """Least-recently-used mapping with at most ``max_entries`` entries and ``max_bytes`` bytes of arrays
    (an entry larger than ``max_bytes`` alone is not kept)."""

    def __init__(self, max_entries: int, max_bytes: int) -> None:
        if max_entries < 1 or max_bytes < 1:
            raise ValueError("a cache needs max_entries >= 1 and max_bytes >= 1")
        self.max_entries = int(max_entries)
        self.max_bytes = int(max_bytes)
        self._data: OrderedDict = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

    def __len__(self) -> int:
        return len(self._data)

    @property
    def nbytes(self) -> int:
        """Bytes of the numpy arrays held."""
        return self._bytes

    def get(self, key, default=None):
        with self._lock:
            value = self._data.get(key)
            if value is None:
                self.misses += 1
                return default
            self._data.move_to_end(key)
            self.hits += 1
            return value

    def put(self, key, value) -> None:
        size = _nbytes(value)
        with self._lock:
            old = self._data.pop(key, None)
            if old is not None:
                self._bytes -= _nbytes(old)
            if size > self.max_bytes:
                return
            self._data[key] = value
            self._bytes += size
            while len(self._data) > self.max_entries or self._bytes > self.max_bytes:
                self._bytes -= _nbytes(self._data.popitem(last=False)[1])

    def clear(self) -> None:
        with self._lock:
            self._data.clear()
            self._bytes = 0
            self.hits = self.misses = 0


MAX_ENTRIES = 8
_LOCK = threading.Lock()
_SEARCHERS: OrderedDict = OrderedDict()
MOVING_ENTRIES = 16
_MOVING: OrderedDict = OrderedDict()
GEOMETRY_ENTRIES = 32
_GEOMETRY: OrderedDict = OrderedDict()
REFERENCE_ENTRIES = 32  # hall16's first 20 s: 45% of its searchers found their reference side kept (most misses are
# pairs' own copies of the older map, teammates moved on: merger.team.tree.at_one_instant)
_REFERENCE: OrderedDict = OrderedDict()


def _hit(store: OrderedDict, key, owner):
    """``store[key]``'s value if it was made for ``owner``, else None (the caller holds ``_LOCK``)."""
    hit = store.get(key)
    return hit[1] if hit is not None and hit[0] is owner else None


def _kept(store: OrderedDict, key, owner, factory, limit: int):
    """``store[key]``'s value if it was made for ``owner`` (the object itself is held with the entry, so
    an id is never mistaken for another's), else ``factory()`` kept there; the last ``limit`` entries."""
    with _LOCK:
        hit = _hit(store, key, owner)
        if hit is not None:
            store.move_to_end(key)
            return hit
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


def reference_side(grid, key: tuple, factory):
    """Arrays that depend on the reference map alone (and ``key``: its center, the ROI, the window, the measure's
    count table), kept for the last ``REFERENCE_ENTRIES`` of them: a map version is the reference of several
    pairs, each searched and then re-verified."""
    return _kept(_REFERENCE, (id(grid),) + key, grid, factory, REFERENCE_ENTRIES)


def moving_side_kept(grid, key: tuple):
    """:func:`moving_side`'s value if it is kept, else None (nothing computed)."""
    with _LOCK:
        return _hit(_MOVING, (id(grid),) + key, grid)


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


def drop_frontier(problem) -> None:
    """Forget ``problem``'s frontier once its reader has run (:func:`merger.team.ambiguity.resolve`: the
    runner-up searches right after the search, on the same problem). Kept for the problem's life, a frontier
    lived as long as any shared result held its alignment (the alignment holds its problem for the guard
    beyond the window): 338 MB in the 32-robot hall's first 3 s."""
    with _LOCK:
        _FRONTIERS.pop(problem, None)


def frontier(problem):
    """The frontier the fast search of ``problem`` left (None if it has not run)."""
    with _LOCK:
        return _FRONTIERS.get(problem)


def clear_all() -> None:
    """Forget every cache the merger keeps between calls: the search's searchers, moving-map and reference-map
    arrays, reference geometries and frontiers. A merge cycle's :class:`merger.team.memo.Memo` belongs to its
    caller and goes with it."""
    with _LOCK:
        _FRONTIERS.clear()
        _SEARCHERS.clear()
        _MOVING.clear()
        _GEOMETRY.clear()
        _REFERENCE.clear()
