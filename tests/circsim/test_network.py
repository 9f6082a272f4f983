"""The simulated network: latency, jitter, loss and out-of-order delivery."""

from __future__ import annotations

import numpy as np
import pytest

from circsim.config.types import NetworkConfig
from circsim.network import Message, Network


def net(seed=0, **kw) -> Network:
    return Network(NetworkConfig(**kw), np.random.default_rng(seed))


def test_fixed_latency_delivers_in_order_at_send_plus_latency():
    n = net(latency_s=0.25)
    for k in range(5):
        m = n.send("Lyon", "Nevers", k, now=k * 1.0)
        assert isinstance(m, Message) and m.arrive_s == pytest.approx(k + 0.25)
    assert n.deliver("Nevers", 0.2) == []
    assert [m.payload for m in n.deliver("Nevers", 2.3)] == [0, 1, 2]
    assert n.deliver("Nevers", 2.3) == []  # delivered once
    assert n.pending("Nevers") == 2 and n.pending() == 2
    assert [m.payload for m in n.deliver("Nevers", 10.0)] == [3, 4]
    assert n.deliver("Lyon", 10.0) == []


def test_broadcast_skips_the_sender_and_inboxes_are_separate():
    n = net(latency_s=0.1)
    msgs = n.broadcast("Lyon", ["Lyon", "Auckland", "Nevers"], "map", now=2.0)
    assert sorted(m.recipient for m in msgs) == ["Auckland", "Nevers"]
    assert [m.sender for m in n.deliver("Auckland", 2.1)] == ["Lyon"]
    assert n.pending("Nevers") == 1 and n.deliver("Lyon", 99.0) == []
    inbox = n.inbox("Nevers")
    assert inbox.pending() == 1 and [m.payload for m in inbox.deliver(2.1)] == ["map"] and inbox.pending() == 0


def test_loss_rate_is_respected():
    n = net(seed=1, loss=0.3)
    got = [n.send("a", "b", k, now=0.0) for k in range(4000)]
    lost = sum(m is None for m in got)
    assert 0.27 < lost / 4000 < 0.33 and n.lost == lost and n.sent == 4000
    assert len(n.deliver("b", 1.0)) == 4000 - lost


def test_jitter_reorders_and_never_arrives_before_sending():
    n = net(seed=2, latency_s=0.05, jitter_s=0.5)
    sent = [n.send("a", "b", k, now=k * 0.1) for k in range(300)]
    assert all(m.arrive_s >= m.sent_s for m in sent)
    delays = np.array([m.arrive_s - m.sent_s for m in sent])
    assert delays.min() >= 0.05 - 1e-12  # jitter only adds to the latency
    out = n.deliver("b", 1e9)
    arrivals = [m.arrive_s for m in out]
    assert arrivals == sorted(arrivals)
    assert [m.payload for m in out] != list(range(300))  # some overtook others


def test_same_seed_same_deliveries():
    def run(seed):
        n = net(seed=seed, latency_s=0.1, jitter_s=0.05, loss=0.2)
        for k in range(50):
            n.broadcast("a", ["a", "b", "c"], k, now=k * 0.5)
        return [(m.payload, m.arrive_s) for r in "bc" for m in n.deliver(r, 1e9)]
    assert run(3) == run(3) != run(4)


def test_jitter_only_adds_delay_half_normal():
    """Issue 12: with jitter, no message arrives sooner than the latency; the extra delay is half-normal
    of scale jitter_s (mean jitter·√(2/π)), so more jitter means later maps, never earlier ones."""
    latency, jitter, k = 1.0, 0.4, 20000
    n = net(seed=5, latency_s=latency, jitter_s=jitter)
    extra = np.array([n.send("a", "b", i, now=0.0).arrive_s - latency for i in range(k)])
    assert extra.min() >= 0.0
    assert extra.mean() == pytest.approx(jitter * np.sqrt(2 / np.pi), rel=0.03)
    assert np.median(extra) == pytest.approx(jitter * 0.6745, rel=0.04)
    means = []
    for j in (0.0, 0.2, 0.8):  # the same draws: mean delay grows with jitter
        m = net(seed=5, latency_s=latency, jitter_s=j)
        means.append(np.mean([m.send("a", "b", i, now=0.0).arrive_s for i in range(2000)]))
    assert means[0] == pytest.approx(latency) and means[0] < means[1] < means[2]
