"""circsim.commands: the scenario argument (a file or a bundled name, ``--set`` and ``--seed`` applied),
the progress observer, and the signals: SIGTERM handled as Ctrl-C from :func:`start` to :func:`finish`
(exit code 143 after it, 130 after Ctrl-C), the handlers restored by :func:`finish`."""

from __future__ import annotations

import argparse
import signal
import threading

import pytest

from circsim.commands import (
    UsageError,
    add_scenario_args,
    begin_work,
    finish,
    interrupted_code,
    load_with_overrides,
    progress_observer,
    resolve_scenario,
    start,
    terminated,
)
from circsim.config.scenario import bundled_scenarios
from circsim.events import Observer


def test_a_scenario_is_a_file_or_a_bundled_name(tmp_path):
    bundled = bundled_scenarios()
    assert resolve_scenario("scene1") == bundled["scene1"]
    f = tmp_path / "scene1"  # a file of that name wins over the bundled one
    f.write_text("name: x\n")
    assert resolve_scenario(str(f)) == f
    with pytest.raises(UsageError) as e:
        resolve_scenario("nowhere")
    assert str(e.value).startswith("nowhere: no such scenario file (bundled scenarios: ")
    assert all(n in str(e.value) for n in bundled)


def test_seed_and_sets_are_applied():
    sc = load_with_overrides("scene1", 42, ["duration_s=7", "robots.speed_mps=0.3"])
    assert sc.seed == 42 and sc.duration_s == 7 and sc.robots.speed_mps == 0.3
    base = load_with_overrides("scene1", None, [])
    assert base.seed != 42 or base.duration_s != 7
    with pytest.raises(ValueError, match="duration_s"):
        load_with_overrides("scene1", None, ["duration_s=soon"])


def test_the_scenario_arguments_parse():
    p = argparse.ArgumentParser()
    add_scenario_args(p)
    a = p.parse_args(["scene2", "--seed", "3", "--set", "a=1", "--set", "b.c=2"])
    assert (a.scenario, a.seed, a.set) == ("scene2", 3, ["a=1", "b.c=2"])
    assert p.parse_args(["x"]).set == [] and p.parse_args(["x"]).seed is None


def test_the_progress_observer_follows_the_ticks():
    sc = load_with_overrides("scene1", None, ["duration_s=5"])
    assert progress_observer(sc, quiet=True) is None
    o = progress_observer(sc, quiet=False)
    assert isinstance(o, Observer)
    o.on_tick(1.25, 12, [])
    assert o.bar.n == round(1.25, 1)
    o.on_end(None)


def test_sigterm_is_ctrl_c_between_start_and_finish():
    assert threading.current_thread() is threading.main_thread()  # signal handlers: the main thread's
    before = (signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT))
    saved = start()
    try:
        assert not terminated() and interrupted_code() == 130
        begin_work()
        handler = signal.getsignal(signal.SIGTERM)
        assert handler is not before[0]
        # the work's Ctrl-C; a process started with Ctrl-C ignored (nohup, a non-interactive shell's background
        # job) keeps it ignored, and SIGTERM still stops it (below)
        ignored = before[1] is signal.SIG_IGN
        assert signal.getsignal(signal.SIGINT) is (signal.SIG_IGN if ignored else signal.default_int_handler)
        with pytest.raises(KeyboardInterrupt):
            handler(signal.SIGTERM, None)
        assert terminated() and interrupted_code() == 143
        # a run's own tick-boundary SIGINT handler gets the SIGTERM instead
        got = []
        signal.signal(signal.SIGINT, lambda s, f: got.append(s))
        handler(signal.SIGTERM, None)
        assert got == [signal.SIGINT]
    finally:
        finish(saved)
    assert signal.getsignal(signal.SIGTERM) is before[0]  # restored
    signal.signal(signal.SIGINT, before[1])
    finish(start())
    assert not terminated() and interrupted_code() == 130  # start() clears it: the next command begins afresh
