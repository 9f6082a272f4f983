"""The merger's caches: a small thread-safe LRU cache bounded in entries and in bytes, a content key for
arrays, and :func:`clear_all` — the one way to empty every cache the merger keeps between calls.

The merger keeps a few derived arrays between searches (polar spectra of a map, sample indices) so
that an unchanged map is not processed again in the next merge cycle. A simulation runs for minutes
and every published map is new, so every such cache must forget: :class:`BoundedCache` evicts the
least recently used entries once it holds more than ``max_entries`` values or ``max_bytes`` bytes of
numpy arrays. Keys are cheap (geometry and a content digest, :func:`array_digest`), never a scan.

No answer depends on a cache (a cached value is a pure function of its key): :func:`clear_all` only
returns memory, e.g. between the independent runs of a sweep worker. Callers outside the merger clear
caches through it, never through a cache module of their own choosing (:mod:`merger.search.caches`
holds the search's).
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict

import numpy as np

from .search import caches as search_caches


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


def clear_all() -> None:
    """Forget every cache the merger keeps between calls: the search's prepared searchers and moving-map
    arrays (:func:`merger.search.caches.clear_all`). A merge cycle's :class:`merger.team.memo.Memo` belongs
    to its caller and goes with it."""
    search_caches.clear_all()
