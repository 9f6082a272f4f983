"""merger.team.verify: ν on the whole maps with its acceptance rule, and the reasons it gives."""

import numpy as np

from merger.grid import FREE_S, OCCUPIED_S, UNKNOWN_S
from merger.team.verify import pairwise, verify


def walls(n=20, seed=0):
    rng = np.random.default_rng(seed)
    return rng.choice([UNKNOWN_S, FREE_S, OCCUPIED_S], size=(n, n), p=[0.2, 0.5, 0.3]).astype(np.uint8)


def test_a_map_against_itself_passes_with_nu_one():
    a = walls()
    v = verify(a, a, nu_min=0.5, min_support=10)
    assert v.passed and v.nu == 1.0 and v.reason == "" and v.support == v.counts.agree > 0


def test_too_little_support_is_refused_before_nu():
    a = walls()
    v = verify(a, a, nu_min=0.5, min_support=10**6, label="Lyon|Nevers")
    assert not v.passed and v.reason.startswith("support of ν(Lyon|Nevers) = ")


def test_a_low_nu_is_refused_with_its_value():
    a, b = walls(seed=1), walls(seed=2)
    v = verify(a, b, nu_min=0.99, min_support=1)
    assert not v.passed and v.nu < 0.99 and v.reason.startswith("ν = ") and "< ν_min 0.99" in v.reason


def test_pairwise_lists_every_pair_once():
    assert pairwise([None] * 3) == [(0, 1), (0, 2), (1, 2)] and pairwise([None]) == []
