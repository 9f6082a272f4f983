"""The merge cycle's thread pool: a cycle's independent searches (merge orders, tree pairs) side by side.

The search kernels release the GIL (numba ``nogil=True``), so threads use every core. Results come back
in input order and each task is a pure function of its inputs, so a cycle's result is the same whatever
the scheduling and the number of threads (``MERGER_THREADS``, default: the machine's cores; 1: none).

A call's items form a batch. The caller computes items itself, and helpers on the pool's threads take
the next item not yet started, as they come free: a call made inside a pooled task (a robot's cycle,
whose pairs are a batch of their own) never waits for an item no thread has started, so nested calls
cannot deadlock, and a thread that finishes its own work early helps with the other batches'. Before,
a nested call ran its items one after the other on its thread: a simulated tick whose robots' cycles
were unequal left cores idle while the longest cycle's pairs ran alone (docs/performance-history.md).
"""

from __future__ import annotations

import contextvars
import os
import threading
import time
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor

_LOCK = threading.Lock()
_POOL: ThreadPoolExecutor | None = None


def max_threads() -> int:
    """The most threads ``MERGER_THREADS`` may ask for: 4 × the machine's cores, at least 8 (more only
    thrash: every search is compute-bound)."""
    return max(8, 4 * (os.cpu_count() or 1))


def threads() -> int:
    """The pool's size: ``MERGER_THREADS`` if set (plain decimal digits, 1 to :func:`max_threads`), else
    the machine's cores. Anything else set (``abc``, ``0``, ``-2``, ``2_0``, ``99999999999999999999``)
    raises ValueError: both command lines check it before any work."""
    text = os.environ.get("MERGER_THREADS", "").strip()
    if not text:
        return os.cpu_count() or 1
    cap = max_threads()
    # int() also takes '2_0' (20), '+3', '٣' (Arabic-Indic 3) and any number of digits: only 0-9, and short
    n = int(text) if text.isascii() and text.isdigit() and len(text) <= 6 else 0
    if not 1 <= n <= cap:
        raise ValueError(f"MERGER_THREADS={text[:40]!r}: expected an integer >= 1 and <= {cap} (4 x the "
                         "machine's cores, at least 8; decimal digits only) (threads per merge cycle; unset: "
                         "one per core)")
    return n


def _pool() -> ThreadPoolExecutor:
    global _POOL
    with _LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=threads(), thread_name_prefix="merger")
        return _POOL


class CpuClock:
    """The CPU time of one computation: its own thread's since the clock started, and that of the items it
    handed to the pool's other threads (:func:`parallel_map`), read on the thread that started it. On a
    machine busy with other threads a computation's wall time grows; its CPU time is what it would take
    alone."""

    def __init__(self) -> None:
        self._t0 = time.thread_time()
        self._others = 0.0
        self._lock = threading.Lock()

    def add(self, seconds: float) -> None:
        with self._lock:
            self._others += seconds

    def ms(self) -> float:
        with self._lock:
            return (time.thread_time() - self._t0 + self._others) * 1e3


_CLOCK: contextvars.ContextVar[CpuClock | None] = contextvars.ContextVar("merger_cpu_clock", default=None)


def start_clock() -> CpuClock:
    """A :class:`CpuClock` for what runs in the current context from now on (the items it hands to the pool
    carry it)."""
    clock = CpuClock()
    _CLOCK.set(clock)
    return clock


class _Batch:
    """One call's items: the next not yet started is taken under a lock, by the caller or a helper."""

    def __init__(self, fn: Callable, items: list) -> None:
        self.fn, self.items = fn, items
        # each item runs in a copy of the caller's context: what the caller set there (the merge cycle's ledger
        # of charged time, merger.team.memo) reaches every thread that computes one of its items
        self.ctx = [contextvars.copy_context() for _ in items]
        self.caller = threading.get_ident()
        self.out: list = [None] * len(items)
        self.err: list = [None] * len(items)
        self.next = 0
        self.left = len(items)
        self.cond = threading.Condition(threading.Lock())

    def help(self) -> None:
        """Compute items until none is left to start."""
        while True:
            with self.cond:
                k = self.next
                if k >= len(self.items):
                    return
                self.next = k + 1
            try:
                clock = None if threading.get_ident() == self.caller else self.ctx[k].get(_CLOCK)
                t0 = time.thread_time()
                self.out[k] = self.ctx[k].run(self.fn, self.items[k])
                if clock is not None:  # an item of the caller's computation, run on another thread
                    clock.add(time.thread_time() - t0)
            except BaseException as e:  # re-raised by the caller, in order
                self.err[k] = e
            with self.cond:
                self.left -= 1
                if self.left == 0:
                    self.cond.notify_all()

    def wait(self) -> None:
        with self.cond:
            while self.left > 0:
                self.cond.wait()


def parallel_map(fn: Callable, items: Iterable) -> list:
    """``[fn(x) for x in items]``, computed by the caller and the pool's threads (in order; the first
    exception, in the items' order, re-raised)."""
    items = list(items)
    n = threads()
    if len(items) < 2 or n < 2:
        return [fn(x) for x in items]
    batch = _Batch(fn, items)
    pool = _pool()
    for _ in range(min(n, len(items)) - 1):
        pool.submit(batch.help)
    batch.help()
    batch.wait()
    for e in batch.err:
        if e is not None:
            raise e
    return batch.out
