"""The one interface every merging algorithm of :mod:`merger.algorithms` answers.

``align(ref, mov, params) -> PairAnswer``: two maps (:class:`merger.team.orders.MapInput`: grid, center in
its own frame, name), the merge settings (:class:`merger.team.orders.MergeParams`) → the placement of map
``mov`` onto map ``ref`` about the centers, x_ref = c_ref + t + R(θ)(x_mov − c_mov) (any rigid placement
has this form, whether the algorithm used the centers or not), its evidence (what the algorithm measured,
plain numbers) and whether the algorithm itself accepts it; a refusal says why in ``reason``.
``score`` orders the accepted answers of a team (the larger, the more trusted: a spanning tree keeps the
strongest, :mod:`merger.algorithms.team`). Algorithms are pure: arrays in, values out, no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..pose import wrap_yaw


@dataclass(frozen=True)
class PairAnswer:
    accepted: bool
    theta_deg: float | None = None
    translation_m: tuple[float, float] = (0.0, 0.0)
    score: float = 0.0
    evidence: dict = field(default_factory=dict)
    reason: str = ""

    def inverse(self) -> PairAnswer:
        """The same placement read the other way: map ``ref`` onto map ``mov`` (θ' = −θ, t' = −R(−θ)t)."""
        if self.theta_deg is None:
            return self
        a = math.radians(-self.theta_deg)
        c, s = math.cos(a), math.sin(a)
        tx, ty = self.translation_m
        return PairAnswer(self.accepted, wrap_yaw(-self.theta_deg), (-(c * tx - s * ty), -(s * tx + c * ty)),
                          self.score, self.evidence, self.reason)


def refused(reason: str, **evidence) -> PairAnswer:
    return PairAnswer(False, None, (0.0, 0.0), 0.0, dict(evidence), reason)


def center_form(affine, ref, mov) -> tuple[float, tuple[float, float]]:
    """(θ, t) about the centers of a 2×3 map of ``mov``'s cell indices (x = column, y = row, a cell's centre
    at its index) onto ``ref``'s: θ from its linear part, t = where it puts c_mov − c_ref."""
    a = affine
    theta = wrap_yaw(math.degrees(math.atan2(a[1][0], a[0][0])))
    gm, gr = mov.grid, ref.grid
    px = ((mov.center[0] - gm.origin[0]) / gm.resolution - 0.5, (mov.center[1] - gm.origin[1]) / gm.resolution - 0.5)
    q = (a[0][0] * px[0] + a[0][1] * px[1] + a[0][2], a[1][0] * px[0] + a[1][1] * px[1] + a[1][2])
    landed = (gr.origin[0] + (q[0] + 0.5) * gr.resolution, gr.origin[1] + (q[1] + 0.5) * gr.resolution)
    return theta, (landed[0] - ref.center[0], landed[1] - ref.center[1])
