"""Results of the merger's pure computations shared by callers that hold the same maps.

Every search and every pair verification is a pure function of its maps (content, geometry, center) and
parameters. The robots of one simulated team hold the same teammates' maps, so they compute the same pair
searches: with 8 robots, each pair of map versions is searched by all 8 (:mod:`merger.team.tree`), and in the
thesis's orders (:mod:`merger.team.orders`) a pair that opens an order is searched by every robot that holds it.
A :class:`Memo` computes each once and hands the same result to the others.

It changes no result (the value is the one the caller would compute: the computations are
deterministic), only the time a simulation takes. So that a robot's reported merge cost stays the cost it
would pay alone, each entry keeps the CPU time its computation took (:class:`merger.team.pool.CpuClock`: on
two cores shared by several robots' cycles, wall time measures the others too), and a caller that takes a
stored result — or waits for another thread computing it — is *charged* that time
(:meth:`Memo.take_charged_ms`, read and reset by the merge cycle; :attr:`merger.team.orders.TeamMergeResult.cost_ms`).
Charges go to the cycle that asked: a ledger in the caller's context, which :mod:`merger.team.pool` carries
to the threads that compute the cycle's items (the robots' cycles of a simulated tick run side by side).

Keys are map versions or content digests (:func:`map_key`), never object identities or scans; the memo
is bounded in entries (an entry may hold grids: an alignment's deferred evidence).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Hashable
from contextvars import ContextVar, copy_context

from ..caches import BoundedCache, array_digest
from .pool import start_clock

MEMO_ENTRIES = 256  # a team of 8 holds 28 pairs; a few map versions of each


def grid_key(grid) -> tuple:
    """A content key of an occupancy grid: its states' digest, shape, resolution and origin."""
    return (array_digest(grid.states), grid.states.shape, float(grid.resolution),
            (float(grid.origin[0]), float(grid.origin[1])))


def map_key(m) -> tuple:
    """A key of a :class:`merger.team.orders.MapInput`: its owner, its ``version`` when it has one (by contract a
    version identifies the owner's grid: a map message's stamp), else its grid's content; and its center."""
    ident = ("version", m.version) if m.version is not None else grid_key(m.grid)
    return (m.name, ident, (float(m.center[0]), float(m.center[1])))


def _timed(compute):
    """``compute()`` and its CPU time (ms), in a context of its own (its clock does not replace the caller's)."""
    clock = start_clock()
    return compute(), clock.ms()


class _Ledger:
    """The time charged to one merge cycle (its own threads' charges add up here)."""

    def __init__(self) -> None:
        self.ms = 0.0
        self.lock = threading.Lock()

    def add(self, ms: float) -> None:
        with self.lock:
            self.ms += ms


class Memo:
    """A bounded store of computed results with their cost (see the module documentation)."""

    def __init__(self, max_entries: int = MEMO_ENTRIES) -> None:
        # entries are counted, not their bytes: values are merger records (small; their grids are shared)
        self._cache = BoundedCache(max_entries, 2**62)
        self._ledger: ContextVar[_Ledger | None] = ContextVar(f"memo_ledger_{id(self)}", default=None)
        self.computed = 0
        self.shared = 0
        self._lock = threading.Lock()  # the counters: a cycle's searches run on threads (merger.team.pool)
        self._running: dict[Hashable, threading.Event] = {}  # keys being computed, set when they are done

    def __len__(self) -> int:
        return len(self._cache)

    def get(self, key: Hashable, compute: Callable[[], object]):
        """The stored value of ``key``, or ``compute()`` (stored with its CPU time). A stored value charges
        its computation's time to the asking cycle (:meth:`take_charged_ms`). A key another thread is
        computing is waited for, not computed twice (robots whose cycles run side by side ask for the same new pairs: in the
        8-robot hall 12% of the computing time went to such duplicates)."""
        while True:
            hit = self._cache.get(key)
            if hit is not None:
                value, ms = hit
                self._charge(ms)
                with self._lock:
                    self.shared += 1
                return value
            with self._lock:
                running = self._running.get(key)
                if running is None:
                    done = self._running[key] = threading.Event()
            if running is None:
                break
            running.wait()  # then stored (or failed, or already evicted: computed here)
        try:
            value, ms = copy_context().run(_timed, compute)
            self._cache.put(key, (value, ms))
            with self._lock:
                self.computed += 1
        finally:
            with self._lock:
                del self._running[key]
            done.set()
        return value

    def _charge(self, ms: float) -> None:
        ledger = self._ledger.get()
        if ledger is None:  # no cycle asked for its charges yet: this context's ledger, from now on
            ledger = _Ledger()
            self._ledger.set(ledger)
        ledger.add(ms)

    def take_charged_ms(self) -> float:
        """The time charged to this context (the calling merge cycle and the threads computing its items)
        since its last call, and a new ledger from now on."""
        ledger = self._ledger.get()
        self._ledger.set(_Ledger())
        return 0.0 if ledger is None else ledger.ms

    def clear(self) -> None:
        self._cache.clear()
        self._ledger.set(None)
        self.computed = self.shared = 0
