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
verified pairs, :func:`merger.team.tree.merge_tree`); ``auto`` chooses one by the team's size. They are one
table, :data:`STRATEGIES_BY_NAME` (a :class:`Strategy` per name with its cycle): the ``strategy`` setting's
allowed values are its keys (:data:`STRATEGIES`), and a merger looks its strategy up once, when it is made.
"""

from __future__ import annotations

from collections.abc import Callable
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

AUTO_ORDERS_MAX_TEAM = 3  # "auto": the thesis's merge orders for teams of up to this many robots, the tree beyond


@dataclass(frozen=True)
class Strategy:
    """A team strategy (the ``strategy`` setting).

    cycle : one merge cycle, ``cycle(merger, inputs, clock, reuse) -> TeamMergeResult`` (the
        :class:`TeamMerger`, its held maps, the cycle's time, its reuse dict or None); None for a choice.
    pairs : its searches are pair searches of raw maps (the tree's edges), not the steps of merge orders
        (the recorder names them so).
    choose : a choice between strategies (``auto``): the name of the one a team of n robots runs.
    cycle_period_s : how often, at most, a robot running it merges by default (seconds; 0: at every new
        map). The simulator's ``merger.cycle_period_s`` when it is not set; a node calling
        :meth:`TeamMerger.cycle` chooses its own rate.
    settled_period_s : the same once the robot's last cycle accepted a placement of its whole team (its
        answers are then re-verified, not sought: ROS multirobot_map_merge re-estimates its transforms at
        ``estimation_rate`` 0.5 Hz); 0: ``cycle_period_s`` always.
    """

    name: str
    cycle: Callable | None = None
    pairs: bool = False
    choose: Callable[[int], str] | None = None
    cycle_period_s: float = 0.0
    settled_period_s: float = 0.0

    def period(self, settled: bool) -> float:
        """The merge period of a robot whose last cycle placed its whole team (``settled``) or not."""
        return self.settled_period_s if settled and self.settled_period_s > 0 else self.cycle_period_s

    def resolve(self, team_size: int) -> Strategy:
        """The strategy a team of ``team_size`` robots runs: itself, or the one it chooses."""
        return self if self.choose is None else STRATEGIES_BY_NAME[self.choose(team_size)]


def _orders_cycle(tm: TeamMerger, inputs: list[MapInput], clock: float, reuse: dict | None) -> TeamMergeResult:
    """The thesis's merge orders; with a tracker, its held hypothesis re-verified first (:mod:`.follow`)."""
    if tm.tracker is not None:
        return merge_team_tracked(inputs, tm.params, tm.tracker, clock, reuse=reuse, memo=tm.memo)
    return merge_team(inputs, tm.params, reuse=reuse, memo=tm.memo)


def _tree_cycle(tm: TeamMerger, inputs: list[MapInput], clock: float, reuse: dict | None) -> TeamMergeResult:
    """The tree of verified pairs (:mod:`.tree`), with the tracker if any."""
    return merge_tree(inputs, tm.params, reuse=reuse, memo=tm.memo, tracker=tm.tracker, now=clock)


TREE_CYCLE_PERIOD_S = 0.5  # the tree strategy's merge period: at most two cycles a second
TREE_SETTLED_PERIOD_S = 2.0  # ... and once a robot holds a placement of its whole team: one cycle per 2 s
# (multirobot_map_merge's estimation_rate, 0.5 Hz; a map arrives from each teammate once per network period,
# 2 s by default). Its first full merge comes at the faster rate, unchanged (unless its first complete placement
# was wrong: then up to 2 s later); once placed, a 16-robot hall's robot re-assembled its team four times per
# round of maps (docs/experiments.md, twelfth pass)


def _auto(team_size: int) -> str:
    """``auto``: the thesis's ``orders`` for up to three robots (the thesis's case: three orders of two
    searches) and the ``tree`` beyond, where the orders grow as N(N−1)/2 orders of N−1 searches per cycle."""
    return "orders" if team_size <= AUTO_ORDERS_MAX_TEAM else "tree"


STRATEGIES_BY_NAME: dict[str, Strategy] = {s.name: s for s in (
    Strategy("auto", choose=_auto),
    Strategy("orders", _orders_cycle),
    # merging at every tick that brought a map, a 16-robot hall's robot ran 4.4 cycles a second, each assembling
    # its whole team again; at 0.5 s the first full merges of halls and rooms of 4-16 robots came within 1.7 s
    # of those, less than a network period (docs/experiments.md, tenth pass)
    Strategy("tree", _tree_cycle, pairs=True, cycle_period_s=TREE_CYCLE_PERIOD_S,
             settled_period_s=TREE_SETTLED_PERIOD_S),
)}
STRATEGIES = tuple(STRATEGIES_BY_NAME)  # the strategy setting's allowed values


def strategy_of(strategy: str, team_size: int) -> Strategy:
    """The :class:`Strategy` a team of ``team_size`` robots runs under the setting ``strategy``."""
    if strategy not in STRATEGIES_BY_NAME:
        raise ValueError(f"strategy must be one of {STRATEGIES}, got {strategy!r}")
    return STRATEGIES_BY_NAME[strategy].resolve(team_size)


def resolve_strategy(strategy: str, team_size: int) -> str:
    """The name of the strategy a team of ``team_size`` robots runs (:func:`strategy_of`): ``auto`` is the
    thesis's ``orders`` for up to three robots and the ``tree`` beyond."""
    return strategy_of(strategy, team_size).name


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
    _strategy: Strategy | None = field(default=None, init=False, repr=False)  # the strategy's object, looked up once

    def __post_init__(self) -> None:
        self.team = tuple(self.team)
        if self.self_name not in self.team:
            raise ValueError(f"{self.self_name!r} is not in the team {self.team}")
        if len(set(self.team)) != len(self.team):
            raise ValueError(f"team names must be unique: {self.team}")
        self._strategy = strategy_of(self.strategy, len(self.team))
        self.strategy = self._strategy.name
        if self.tracker is None and self.params.research_mode.tracks:
            self.tracker = Tracker.from_params(self.params, self.memo)

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
        result = self._strategy.cycle(self, self.inputs(), clock, reuse)
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
