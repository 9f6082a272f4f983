"""Shared hypotheses (issue 10, item 4): robots exchange accepted alignments, and adopt one only on evidence.

In the thesis every robot computes alone, and robots may hold different global maps. Here a robot may
broadcast the alignment it holds (:class:`HypothesisMessage`: its placements of every map onto its own
frame, with the ν it verified). A receiver expresses the placements in its own frame (:func:`reframe`,
:func:`merger.team.frames.compose`), verifies them on the maps *it* holds with the whole-map rule of
:mod:`merger.team.orders` (every pair of placed maps: ν ≥ ν_min and support ≥ min_support,
:func:`verify_placements`), verifies the alignment it holds on the same maps, and adopts the received one
only when it passes and its Σν there is higher (:func:`adopt`). Σν over the pairs of placed maps: on the
same maps it orders hypotheses as their mean ν does, and a hypothesis that verifiably places more maps
has more pairs. Its own hypothesis sent back to it (by a robot that adopted it) scores the same and is
not adopted again.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from .frames import Warps, compose, merged_on_frame0
from .params import MapInput, MergeParams, OrderResult, Placement, TeamMergeResult
from .verify import pairwise


@dataclass(frozen=True, eq=False)
class HypothesisMessage:
    """An accepted alignment as it travels: the sender, when it accepted it (``stamp``), every placed map's
    placement onto the sender's frame (x_s = c_s + t + R(θ)(x − c), about each robot's given center) and
    the evidence the sender had (ν per pair, Σν)."""

    robot: str
    stamp: float
    placements: dict[str, Placement]
    nu: dict[str, float]
    nu_sum: float

    def to_dict(self) -> dict:
        return {"robot": self.robot, "stamp": self.stamp, "nu": dict(self.nu), "nu_sum": self.nu_sum,
                "placements": {k: {"theta_deg": th, "translation_m": list(t)} for k, (th, t) in self.placements.items()}}


def hypothesis_of(result: TeamMergeResult, stamp: float) -> HypothesisMessage:
    """The message of an accepted merge result (its chosen hypothesis, in the merging robot's frame)."""
    if result.chosen is None:
        raise ValueError("only an accepted alignment is shared")
    c = result.chosen
    place = {k: (float(c.theta_deg[k]), tuple(map(float, c.translation(k)))) for k in c.theta_deg}
    return HypothesisMessage(result.frame, float(stamp), place, dict(c.nu), c.nu_sum)


def reframe(placements: dict[str, Placement], frame: str, base: str) -> dict[str, Placement]:
    """Placements onto robot ``frame``'s map frame → onto robot ``base``'s (both must be placed)."""
    return compose(placements, frame, base)


def verify_placements(maps: list[MapInput], place: dict[str, Placement], params: MergeParams,
                      warps: Warps | None = None) -> OrderResult:
    """The hypothesis ``place`` (per map name, onto ``maps[0]``'s frame) verified on ``maps`` with the
    whole-map rule of :mod:`merger.team.orders`: every pair ν ≥ ν_min with support ≥ min_support. Maps that
    ``place`` does not place are left out."""
    sub = [m for m in maps if m.name in place]
    if not sub or sub[0] is not maps[0]:
        raise ValueError(f"the hypothesis must place {maps[0].name!r}, the frame it is verified in")
    warps = Warps(sub) if warps is None else warps
    p = {i: place[m.name] for i, m in enumerate(sub)}
    checks = {f"{sub[i].name}|{sub[j].name}": warps.check(i, p[i], j, p[j], params) for i, j in pairwise(sub)}
    failed = [c.reason for c in checks.values() if not c.passed]
    if len(sub) < 2:
        failed.append("it places no map held besides the robot's own")
    return OrderResult(tuple(m.name for m in sub), {m.name: place[m.name][0] for m in sub}, (), checks, not failed,
                       "; ".join(failed), {m.name: tuple(place[m.name][1]) for m in sub})


@dataclass(frozen=True, eq=False)
class Adoption:
    """What a robot made of a received hypothesis.

    received : the hypothesis in the robot's frame, verified on its maps (None: it could not be).
    nu_sum_received, nu_sum_current : Σν of the received hypothesis and of the one held, on the same maps
        (the held one: None when the robot holds none, or it no longer passes there).
    result : the adopted hypothesis as the robot's new held result (None when refused).
    """

    sender: str
    stamp: float
    adopted: bool
    reason: str
    received: OrderResult | None = None
    nu_sum_received: float | None = None
    nu_sum_current: float | None = None
    result: TeamMergeResult | None = None

    def to_dict(self) -> dict:
        return {"sender": self.sender, "stamp": self.stamp, "adopted": self.adopted, "reason": self.reason,
                "nu_sum_received": self.nu_sum_received, "nu_sum_current": self.nu_sum_current,
                "received": None if self.received is None else self.received.to_dict()}


def adopt(maps: list[MapInput], msg: HypothesisMessage, current: TeamMergeResult | None,
          params: MergeParams) -> Adoption:
    """Whether the robot that holds ``maps`` (its own first) and the alignment ``current`` adopts ``msg``
    (see the module notes); the adopted hypothesis comes with its merged map."""
    t0 = time.perf_counter()
    me = maps[0].name
    if me not in msg.placements:
        return Adoption(msg.robot, msg.stamp, False, f"{msg.robot}'s hypothesis does not place {me}")
    mine = reframe(msg.placements, msg.robot, me)
    held = [m for m in maps if m.name in mine]
    warps = Warps(held)
    got = verify_placements(held, mine, params, warps)
    if not got.accepted:
        return Adoption(msg.robot, msg.stamp, False, f"{msg.robot}'s hypothesis fails on {me}'s maps: {got.reason}",
                        got, got.nu_sum)
    cur_sum = None
    if current is not None and current.chosen is not None:
        c = current.chosen
        cur_place = {k: (c.theta_deg[k], c.translation(k)) for k in c.theta_deg}
        cur = verify_placements([m for m in maps if m.name in cur_place], cur_place, params)
        cur_sum = cur.nu_sum if cur.accepted else None
    if cur_sum is not None and not got.nu_sum > cur_sum:
        return Adoption(msg.robot, msg.stamp, False, f"{msg.robot}'s hypothesis verifies on {me}'s maps but "
                        f"scores no higher: Σν {got.nu_sum:.3f} vs {cur_sum:.3f} held", got, got.nu_sum, cur_sum)
    merged, layers = merged_on_frame0(held, {i: mine[m.name] for i, m in enumerate(held)}, warps)
    res = TeamMergeResult(me, (got,), got, merged, layers, (time.perf_counter() - t0) * 1e3)
    why = "none held" if cur_sum is None else f"Σν {got.nu_sum:.3f} > {cur_sum:.3f} held"
    return Adoption(msg.robot, msg.stamp, True, f"adopted {msg.robot}'s hypothesis ({why})", got, got.nu_sum,
                    cur_sum, res)
