"""merger.team.pool: a merge cycle's searches on threads give the cycle computed on one thread, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from merger.caches import clear_all
from merger.synthetic import window_case
from merger.team.orders import MapInput, MergeParams, merge_team
from merger.team.pool import parallel_map, threads
from merger.team.tree import merge_tree


def _maps():
    out = []
    for k, seed in enumerate((1, 2, 3)):
        c = window_case(seed, "views", roi_m=(5.0, 5.0), window_m=(0.2, 0.2))
        if k == 0:
            out += [MapInput("A", c.ref, c.center_ref), MapInput("B", c.moving, c.center_moving)]
        else:
            out.append(MapInput("CDE"[k], c.moving, c.center_moving))
    return out


@pytest.mark.parametrize("text, n", [("3", 3), (" 2 ", 2), ("", None)])
def test_merger_threads_is_an_integer_or_unset(monkeypatch, text, n):
    import os

    monkeypatch.setenv("MERGER_THREADS", text)
    assert threads() == (n or os.cpu_count() or 1)


@pytest.mark.parametrize("text", ["abc", "0", "-2", "1.5"])
def test_merger_threads_that_is_not_a_count_is_refused(monkeypatch, text):
    """``MERGER_THREADS=abc`` silently meant every core (issue 37); the CLIs turn this into exit 2."""
    monkeypatch.setenv("MERGER_THREADS", text)
    with pytest.raises(ValueError, match="MERGER_THREADS=.*expected an integer >= 1"):
        threads()


def test_parallel_map_keeps_the_order_and_reraises():
    assert parallel_map(lambda x: x * x, range(20)) == [x * x for x in range(20)]
    with pytest.raises(ZeroDivisionError):
        parallel_map(lambda x: 1 // x, [2, 1, 0, 3])


@pytest.mark.parametrize("merge", [merge_team, merge_tree])
def test_a_cycle_on_threads_equals_the_cycle_on_one_thread(monkeypatch, merge):
    maps = _maps()
    params = MergeParams(roi_m=5.0, window_m=0.2)
    monkeypatch.setenv("MERGER_THREADS", "1")
    clear_all()
    one = merge(maps, params).to_dict()
    monkeypatch.setenv("MERGER_THREADS", "2")
    clear_all()
    two = merge(maps, params).to_dict()
    for d in (one, two):
        d.pop("cost_ms", None)
    assert _strip(one) == _strip(two)


def _strip(d):
    """The result without wall times."""
    if isinstance(d, dict):
        return {k: _strip(v) for k, v in d.items() if not k.endswith("_ms")}
    if isinstance(d, list):
        return [_strip(v) for v in d]
    if isinstance(d, float) and np.isnan(d):
        return "nan"
    return d


def test_calls_nested_inside_pooled_items_finish_and_keep_their_order(monkeypatch):
    """A robot's cycle (an item of the tick's batch) hands its pairs to the pool: nested batches, three deep
    here, with every pool thread busy, finish without waiting on an item no thread has started."""
    import threading
    import time

    monkeypatch.setenv("MERGER_THREADS", "2")

    def leaf(x):
        time.sleep(0.002)
        return x * x

    def mid(x):
        return sum(parallel_map(leaf, range(x, x + 5)))

    def top(x):
        return parallel_map(mid, range(x, x + 4))

    out = {}
    t = threading.Thread(target=lambda: out.setdefault("r", parallel_map(top, range(6))))
    t.start()
    t.join(30)
    assert not t.is_alive()
    assert out["r"] == [[sum(v * v for v in range(m, m + 5)) for m in range(x, x + 4)] for x in range(6)]
