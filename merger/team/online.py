"""Online merging state of one robot (thesis 3.3.1, online experiments).

Each robot keeps the newest map of every teammate (and its own), tagged with the sender and a time
stamp. Every new map triggers a merge cycle over the maps held (``min_maps`` of them at least: a
partial team merges what it has); an accepted hypothesis replaces the kept alignment, a rejected cycle
never discards a good earlier one. A cycle reuses the robot's own earlier search of a pair of maps that
has not changed since (the searches are deterministic: same result).

With shared hypotheses (:mod:`merger.team.shared`), the robot broadcasts the alignment it holds
(:meth:`TeamMerger.hypothesis`) and weighs a teammate's (:meth:`TeamMerger.consider`): it adopts it
only when it verifies on the robot's own maps and scores higher there than the alignment it holds.

Two strategies: ``orders`` (the thesis: every merge order, :func:`merger.team.orders.merge_team`) and ``tree``
(pairwise alignments kept per map version, the team assembled along a maximum spanning tree of the
verified pairs, :func:`merger.team.tree.merge_tree`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..grid import OccupancyGrid
from .follow import merge_team_tracked
from .memo import Memo
from .orders import merge_team
from .params import MapInput, MergeParams, TeamMergeResult
from .shared import Adoption, HypothesisMessage, adopt, hypothesis_of
from .track import Tracker
from .tree import merge_tree

STRATEGIES = ("auto", "orders", "tree")
AUTO_ORDERS_MAX_TEAM = 3  # "auto": the thesis's merge orders for teams of up to this many robots, the tree beyond


def resolve_strategy(strategy: str, team_size: int) -> str:
    """The strategy a team of ``team_size`` robots runs: ``auto`` is the thesis's ``orders`` for up to
    three robots (the thesis's case: three orders of two searches) and the ``tree`` beyond, where the
    orders grow as N(N−1)/2 orders of N−1 searches per cycle."""
    if strategy == "auto":
        return "orders" if team_size <= AUTO_ORDERS_MAX_TEAM else "tree"
    return strategy


@dataclass(frozen=True, eq=False)
class MapMessage:
    """A map as it travels: who made it, when (its stamp), the grid and the center in its frame, and
    (optional) the robot's path in that frame up to the stamp, rows (t, x, y) (:class:`MapInput`)."""

    robot: str
    stamp: float
    grid: OccupancyGrid
    center: tuple[float, float]
    trajectory: np.ndarray | None = field(default=None, repr=False)


@dataclass
class TeamMerger:
    """Per-robot merger state.

    Parameters
    ----------
    self_name : the robot that merges; results are expressed in its map frame.
    team : names of all robots whose maps are merged (``self_name`` included).
    params : merge parameters.
    min_maps : merge once this many maps are held, own map included (default: the whole team; 2: any
        pair; more than the team: the whole team).
    strategy : "auto" (default: "orders" up to three robots, "tree" beyond — :func:`resolve_strategy`),
        "orders" (the thesis's merge orders) or "tree" (verified pairs, maximum spanning tree).
    """

    self_name: str
    team: tuple[str, ...]
    params: MergeParams = field(default_factory=MergeParams)
    min_maps: int | None = None
    maps: dict[str, MapMessage] = field(default_factory=dict)
    current: TeamMergeResult | None = None
    current_stamp: float | None = None
    cycles: int = 0
    reuse: bool = True  # reuse the pair alignment of two unchanged maps from the previous cycle
    strategy: str = "auto"
    adopted: int = 0  # received hypotheses adopted
    _pairs: dict = field(default_factory=dict, repr=False)
    memo: Memo | None = field(default=None, repr=False)  # results shared with teammates' mergers (merger.team.memo)
    tracker: Tracker | None = field(default=None, repr=False)  # research "on_change": merger.team.track

    def __post_init__(self) -> None:
        self.team = tuple(self.team)
        if self.self_name not in self.team:
            raise ValueError(f"{self.self_name!r} is not in the team {self.team}")
        if len(set(self.team)) != len(self.team):
            raise ValueError(f"team names must be unique: {self.team}")
        if self.strategy not in STRATEGIES:
            raise ValueError(f"strategy must be one of {STRATEGIES}, got {self.strategy!r}")
        self.strategy = resolve_strategy(self.strategy, len(self.team))
        if self.tracker is None and self.params.research == "on_change":
            self.tracker = Tracker.from_params(self.params)

    def receive(self, msg: MapMessage) -> bool:
        """Store a map; an older stamp than the one held (out-of-order delivery) is dropped."""
        if msg.robot not in self.team:
            raise ValueError(f"map from {msg.robot!r}, who is not in the team {self.team}")
        held = self.maps.get(msg.robot)
        if held is not None and held.stamp >= msg.stamp:
            return False
        self.maps[msg.robot] = msg
        return True

    def ready(self) -> bool:
        need = len(self.team) if self.min_maps is None else min(self.min_maps, len(self.team))
        return self.self_name in self.maps and len(self.maps) >= max(2, need)

    def inputs(self) -> list[MapInput]:
        """The held maps, own map first, then teammates in team order."""
        names = [self.self_name] + [n for n in self.team if n != self.self_name and n in self.maps]
        return [MapInput(n, self.maps[n].grid, self.maps[n].center, self.maps[n].stamp, self.maps[n].trajectory)
                for n in names]

    def cycle(self, now: float | None = None) -> TeamMergeResult:
        """Run a merge cycle over the held maps; keep its alignment if it is accepted."""
        if not self.ready():
            raise RuntimeError(f"{self.self_name}: not enough maps to merge ({sorted(self.maps)})")
        clock = float(self.cycles) if now is None else float(now)  # without a clock: a second per cycle
        reuse = self._pairs if self.reuse else None
        if self.strategy == "tree":
            result = merge_tree(self.inputs(), self.params, reuse=reuse, memo=self.memo, tracker=self.tracker,
                                now=clock)
        elif self.tracker is not None:
            result = merge_team_tracked(self.inputs(), self.params, self.tracker, clock, reuse=reuse, memo=self.memo)
        else:
            result = merge_team(self.inputs(), self.params, reuse=reuse, memo=self.memo)
        self.cycles += 1
        if result.accepted:
            self.current = result
            self.current_stamp = now
        return result

    def hypothesis(self) -> HypothesisMessage | None:
        """The alignment held, as a message to share (None: none held)."""
        if self.current is None:
            return None
        return hypothesis_of(self.current, self.current_stamp if self.current_stamp is not None else 0.0)

    def consider(self, msg: HypothesisMessage, now: float | None = None) -> Adoption:
        """Weigh a teammate's hypothesis (:func:`merger.team.shared.adopt`); an adopted one becomes the held
        alignment, as an accepted merge cycle's does."""
        if msg.robot not in self.team or msg.robot == self.self_name:
            raise ValueError(f"hypothesis from {msg.robot!r}: not a teammate of {self.self_name!r} ({self.team})")
        if self.self_name not in self.maps:
            return Adoption(msg.robot, msg.stamp, False, f"{self.self_name} holds no map of its own yet")
        a = adopt(self.inputs(), msg, self.current, self.params)
        if a.adopted:
            self.current = a.result
            self.current_stamp = msg.stamp if now is None else now
            self.adopted += 1
        return a

    def update(self, msg: MapMessage, now: float | None = None) -> TeamMergeResult | None:
        """Take a new map and run a merge cycle; returns the cycle (None if not ready or stale)."""
        if not self.receive(msg) or not self.ready():
            return None
        return self.cycle(msg.stamp if now is None else now)
