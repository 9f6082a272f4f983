"""merger.team.memo: results shared by content key, charged at their cost, bounded."""

import time

import numpy as np

from merger.grid import OCCUPIED_S, OccupancyGrid
from merger.team.memo import Memo, grid_key, map_key
from merger.team.orders import MapInput


def _burn(ms: float) -> None:
    """Compute for ``ms`` of this thread's CPU time (the memo charges CPU time, not sleep)."""
    t0 = time.thread_time()
    while time.thread_time() - t0 < ms / 1e3:
        pass


def _grid(seed: int = 0) -> OccupancyGrid:
    rng = np.random.default_rng(seed)
    return OccupancyGrid(rng.integers(0, 3, (40, 50)).astype(np.uint8), 0.05, (-1.0, -1.25))


def test_a_result_is_computed_once_and_charged_to_every_later_caller():
    memo = Memo()
    calls = []

    def compute():
        calls.append(1)
        _burn(20)
        return {"answer": 42}

    first = memo.get(("pair", 1), compute)
    assert memo.take_charged_ms() == 0.0  # the first caller computed it: nothing charged
    second = memo.get(("pair", 1), compute)
    third = memo.get(("pair", 1), compute)
    assert first is second is third and calls == [1]
    charged = memo.take_charged_ms()
    assert charged >= 2 * 15.0  # two callers, each charged the ~20 ms the computation took
    assert memo.take_charged_ms() == 0.0  # taken: reset
    assert (memo.computed, memo.shared) == (1, 2)


def test_keys_follow_content_not_identity():
    g = _grid()
    same = OccupancyGrid(g.states.copy(), g.resolution, g.origin)
    assert grid_key(g) == grid_key(same)
    changed = g.states.copy()
    changed[3, 4] = OCCUPIED_S if changed[3, 4] != OCCUPIED_S else 0
    assert grid_key(OccupancyGrid(changed, g.resolution, g.origin)) != grid_key(g)
    assert grid_key(OccupancyGrid(g.states, g.resolution, (0.0, 0.0))) != grid_key(g)  # geometry counts
    a = MapInput("Lyon", g, (0.1, 0.2))
    assert map_key(a) == map_key(MapInput("Lyon", same, (0.1, 0.2)))  # without a version: the content
    assert map_key(a) != map_key(MapInput("Lyon", g, (0.1, 0.25)))  # the center counts
    assert map_key(a) != map_key(MapInput("Oslo", g, (0.1, 0.2)))  # and the owner
    # with a version (a map message's stamp, which identifies the owner's grid): the version
    v1 = MapInput("Lyon", g, (0.1, 0.2), version=1.5)
    assert map_key(v1) == map_key(MapInput("Lyon", same, (0.1, 0.2), version=1.5))
    assert map_key(v1) != map_key(MapInput("Lyon", g, (0.1, 0.2), version=2.5))


def test_the_memo_is_bounded():
    memo = Memo(max_entries=5)
    for k in range(20):
        memo.get(k, lambda k=k: k * k)
    assert len(memo) == 5
    assert memo.get(19, lambda: -1) == 361  # recent entries stay
    assert memo.get(0, lambda: -1) == -1  # old ones were evicted: computed again
    memo.clear()
    assert len(memo) == 0 and memo.take_charged_ms() == 0.0


def test_a_key_being_computed_is_waited_for_and_charged_its_computing_time():
    """Two robots' cycles asking for one new pair at once: it is computed once; the one that waited is charged
    its CPU time as computed (the waiter's own CPU time does not contain it)."""
    import threading

    memo = Memo()
    calls, out = [], {}

    def compute():
        calls.append(1)
        _burn(200)
        return object()

    def first():
        memo.take_charged_ms()
        out["first"] = (memo.get("pair", compute), memo.take_charged_ms())

    def second():
        memo.take_charged_ms()
        time.sleep(0.05)  # the first is computing it by now
        out["second"] = (memo.get("pair", compute), memo.take_charged_ms())

    threads = [threading.Thread(target=first), threading.Thread(target=second)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert calls == [1] and out["first"][0] is out["second"][0]
    assert out["first"][1] == 0.0  # computed it
    assert 190.0 <= out["second"][1] < 400.0
    assert (memo.computed, memo.shared) == (1, 1)


def test_charges_go_to_the_cycle_that_asked_even_from_the_pool_s_threads(monkeypatch):
    """Robots' cycles run side by side and spread their pairs over the pool's threads: each cycle's charged
    time is the time of the results it took, not its teammates'. Here b's cycle takes a 200 ms result while
    a's is between its start and its end."""
    import threading

    from merger.team.pool import parallel_map

    monkeypatch.setenv("MERGER_THREADS", "2")
    memo = Memo()
    for k, ms in enumerate([30, 30, 30, 30, 200]):  # stored results and the CPU time they took
        memo.get(k, lambda ms=ms: _burn(ms))
    memo.take_charged_ms()
    out, a_started, b_done = {}, threading.Event(), threading.Event()

    def take(k):
        if k == 3:
            a_started.set()
            b_done.wait(5)
        return memo.get(k, lambda: None)

    def cycle_a():
        memo.take_charged_ms()  # a cycle's start
        parallel_map(take, [0, 1, 2, 3])
        out["a"] = memo.take_charged_ms()

    def cycle_b():
        a_started.wait(5)
        memo.take_charged_ms()
        memo.get(4, lambda: None)
        out["b"] = memo.take_charged_ms()
        b_done.set()

    threads = [threading.Thread(target=cycle_a), threading.Thread(target=cycle_b)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert 4 * 28.0 <= out["a"] < 4 * 60.0 and 195.0 <= out["b"] < 300.0


def test_a_computation_s_cpu_clock_counts_the_items_it_hands_to_the_pool(monkeypatch):
    """A cycle's CPU time is its own thread's and that of its items computed on the pool's other threads —
    not its wall time, which on busy cores also measures the others."""
    from merger.team.pool import parallel_map, start_clock

    monkeypatch.setenv("MERGER_THREADS", "2")
    clock = start_clock()
    parallel_map(lambda _: _burn(40), range(6))
    assert 6 * 38.0 <= clock.ms() < 6 * 80.0
    inner = {}

    def item(k):  # an item that starts a clock of its own: the outer clock still counts it once
        c = start_clock()
        _burn(30)
        inner[k] = c.ms()

    clock = start_clock()
    parallel_map(item, range(4))
    assert 4 * 28.0 <= clock.ms() < 4 * 60.0 and all(25.0 <= v < 60.0 for v in inner.values())
