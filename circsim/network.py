"""A simulated network between robots: latency, jitter and loss, delivered by simulated time.

Messages sent at time t arrive at ``t + latency + jitter * |N(0, 1)|`` unless lost (probability
``loss``): ``latency`` is the smallest delay and jitter only adds to it (a half-normal extra delay of
scale ``jitter``: mean ``jitter·√(2/π)`` ≈ 0.80·jitter, median ≈ 0.67·jitter, 95 % below ≈ 1.96·jitter).
A zero-mean jitter clipped at 0 would deliver half the messages early, so that more jitter made merging
faster. Each recipient has an inbox; :meth:`Network.deliver` hands over everything that has arrived by
``now`` in arrival order, so a later message can overtake an earlier one.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass
from typing import Any

from .config.types import NetworkConfig


@dataclass(frozen=True, eq=False)  # payloads are arrays or grids: identity, not value, comparison
class Message:
    """A message in flight or delivered; ``seq`` orders messages sent in the same network."""

    sender: str
    recipient: str
    sent_s: float
    arrive_s: float
    payload: Any
    seq: int


class Network:
    """Point-to-point message passing with per-recipient inboxes.

    Parameters
    ----------
    config : latency, jitter and loss.
    rng : source of the delay and loss draws (one normal and one uniform per message sent).
    """

    def __init__(self, config: NetworkConfig, rng) -> None:
        self.config = config
        self._rng = rng
        self._inbox: dict[str, list[tuple[float, int, Message]]] = {}
        self._seq = 0
        self.sent = 0
        self.lost = 0
        self.delivered = 0

    def send(self, sender: str, recipient: str, payload: Any, now: float) -> Message | None:
        """Send ``payload``; returns the message in flight, or ``None`` if it was lost."""
        z = float(self._rng.standard_normal())
        u = float(self._rng.random())
        self.sent += 1
        seq = self._seq
        self._seq += 1
        if u < self.config.loss:
            self.lost += 1
            return None
        delay = self.config.latency_s + self.config.jitter_s * abs(z)  # jitter only delays
        msg = Message(sender, recipient, float(now), float(now) + delay, payload, seq)
        heapq.heappush(self._inbox.setdefault(recipient, []), (msg.arrive_s, seq, msg))
        return msg

    def broadcast(self, sender: str, recipients, payload: Any, now: float) -> list[Message]:
        """Send ``payload`` to every recipient but the sender; returns the messages not lost."""
        out = []
        for r in recipients:
            if r != sender:
                m = self.send(sender, r, payload, now)
                if m is not None:
                    out.append(m)
        return out

    def deliver(self, recipient: str, now: float) -> list[Message]:
        """Messages for ``recipient`` that have arrived by ``now``, in arrival order (ties: send order)."""
        q = self._inbox.get(recipient)
        out: list[Message] = []
        while q and q[0][0] <= now:
            out.append(heapq.heappop(q)[2])
        self.delivered += len(out)
        return out

    def inbox(self, recipient: str) -> Inbox:
        """``recipient``'s inbox: ``network.inbox("Lyon").deliver(now)``."""
        return Inbox(self, recipient)

    def pending(self, recipient: str | None = None) -> int:
        """Messages still in flight (to ``recipient``, or to anyone)."""
        if recipient is not None:
            return len(self._inbox.get(recipient, ()))
        return sum(len(q) for q in self._inbox.values())


@dataclass(frozen=True, eq=False)
class Inbox:
    """One robot's view of the network: what has arrived for it."""

    network: Network
    recipient: str

    def deliver(self, now: float) -> list[Message]:
        return self.network.deliver(self.recipient, now)

    def pending(self) -> int:
        return self.network.pending(self.recipient)
