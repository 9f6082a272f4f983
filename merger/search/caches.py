"""The search's only cache: the prepared searcher of the last problems, and :func:`clear_all`.

A merge cycle asks several questions of one problem object (the answer, then perhaps the runner-up,
the guard beyond the window, a rival's values): they share one :class:`merger.search.engine.Searcher`
(its lattice tables and the moving ROIs it computed), kept here by the problem's identity for the
last ``MAX_ENTRIES`` problems. Values never depend on the cache: a searcher is a pure function of its
problem. Numba's on-disk cache of compiled kernels is separate (``NUMBA_CACHE_DIR``).
"""

from __future__ import annotations

import threading
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


def clear_all() -> None:
    """Forget every cached searcher (memory between independent runs, e.g. sweep workers)."""
    with _LOCK:
        _SEARCHERS.clear()
