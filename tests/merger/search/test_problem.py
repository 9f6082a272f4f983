"""merger.search.problem: an Alignment is a frozen value; its one lazy piece of evidence (the guard beyond
the window) is computed once, on first access, thread-safe, and pickling answers it."""

import dataclasses
import pickle
import threading

import numpy as np
import pytest

from merger.measures import Counts
from merger.search import Alignment, BeyondQuery


def alignment(query=None):
    return Alignment(12.0, 0.5, Counts(3, 1), "similarity", "fast", 8.0, np.zeros(360), (190.0, 0.25),
                     window_m=0.2, beyond_query=query)


def test_an_alignment_is_frozen_and_what_it_derives_follows_its_fields():
    al = alignment()
    with pytest.raises(dataclasses.FrozenInstanceError):
        al.theta_deg = 1.0
    assert al.margin == 0.25 and al.has_evidence  # score 0.5 - runner-up 0.25
    assert al.theta_grid_deg == 12.0 and al.translation_grid_m == (0.0, 0.0)  # unrefined: the grid answer
    d = al.to_dict()
    assert (d["agree"], d["disagree"], d["support"]) == (3, 1, 4)
    assert (d["runner_up_deg"], d["runner_up_score"]) == (190.0, 0.25)
    assert al.beyond is None and d["beyond"] is None  # no guard asked
    # numpy scalars in, plain floats out (the value pickles and serialises as JSON)
    al = Alignment(1.0, 0.0, Counts(0, 0), "ncc", "fast", 8.0, np.zeros(360), (np.int64(190), np.float32(0.25)),
                   translation_m=(np.float32(0.5), np.int64(-1)))
    assert [type(v) for v in (*al.runner_up, *al.translation_m)] == [float] * 4
    assert al.runner_up == (190.0, 0.25) and al.translation_m == (0.5, -1.0) and not al.has_evidence


def test_the_guard_runs_once_on_first_access_even_from_many_threads():
    calls = []
    gate = threading.Event()

    def guard(problem, best_value, answer):
        gate.wait(5)
        calls.append(answer)
        return (30, (0.5, -0.25), 0.75)

    al = alignment(BeyondQuery(None, 0.5, (12.0, (0, 0)), guard))
    assert calls == []  # nothing computed at construction
    out = []
    threads = [threading.Thread(target=lambda: out.append(al.beyond)) for _ in range(4)]
    for t in threads:
        t.start()
    gate.set()
    for t in threads:
        t.join()
    assert calls == [(12.0, (0, 0))] and out == [(30.0, (0.5, -0.25), 0.75)] * 4


def test_pickling_answers_the_guard_and_drops_the_question():
    al = alignment(BeyondQuery(None, 0.5, (12.0, (0, 0)), lambda problem, best_value, answer: None))
    back = pickle.loads(pickle.dumps(al))
    assert back.beyond is None and back.beyond_query is None and back.theta_deg == al.theta_deg
