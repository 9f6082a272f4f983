"""The team's parameter set and value types: :class:`MergeParams` (every setting of a merge cycle, with
its one default and its one rule), the maps to merge (:class:`MapInput`) and what a cycle answers
(:class:`OrderResult`, :class:`TeamMergeResult`, placements as :data:`Placement`).

Every strategy (:mod:`merger.team.orders`, :mod:`.tree`, :mod:`.follow`, :mod:`.shared`), the
simulation bench (its scenarios' ``merger`` section is these settings plus the bench's own:
:class:`circsim.config.scenario.MergerSettings`) and the command lines read them from here;
:mod:`merger.team.orders` re-exports them.

One default per setting: MergeParams's field default (``merger.align`` reads the same constants). The
search's own settings take theirs from :mod:`merger.settings` (``DEFAULT_ROI_M``,
``DEFAULT_WINDOW_M``, ``DEFAULT_MEASURE``, ``ROI_MIN_SUPPORT``), which
:class:`~merger.search.RotationProblem` shares; the contrast rule's and the tracking's from :mod:`.defaults`,
as :mod:`.evidence` and :mod:`.track` do (settings flow down: at run time this module imports nothing else of
merger/team/). ``verification`` and ``research`` name entries of its tables: :attr:`MergeParams.verification_rule`
and ``.research_mode`` are the objects.

One rule per setting: :data:`RULES`, a rule ``rule(value, key) -> value`` per MergeParams field holding
its range and its words (``rule.expected``, ``rule.why``); a refusal is a
:class:`~merger.settings.SettingError` ``key`` + " must be <expected>, got <value>", one line naming
the setting as its caller knows it (``nu_min``, a scenario's ``merger.nu_min``, a command line's
``--nu-min``). MergeParams, the scenario loader (:data:`circsim.config.scenario.MERGER_CHECKS`) and the
command lines (:func:`merger.cli.params_from`) call them; the search's settings' rules are
:mod:`merger.settings`'s (``check_roi``, ``check_window``, ``check_measure``, ``check_floor``), and
the one rule between two settings, ``window_m`` ≤ ``roi_m`` / 4, is ``check_window`` with both.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING

import numpy as np

from ..grid import OccupancyGrid
from ..search import SEARCH_METHODS
from ..search.problem import Alignment, angle_diff_deg
from ..settings import (
    DEFAULT_MEASURE,
    DEFAULT_ROI_M,
    DEFAULT_WINDOW_M,
    FLOOR_EXPECTED,
    MEASURE_EXPECTED,
    ROI_MIN_SUPPORT,
    SettingError,
    check_floor,
    check_measure,
    check_roi,
    check_window,
)
from .defaults import (
    CONTRAST_MIN,
    RESEARCH_CHANGE,
    RESEARCH_DEFAULT,
    RESEARCH_DROP,
    RESEARCH_MODES,
    RESEARCH_PERIOD_S,
    TEAMMATE_RADIUS_M,
    TEAMMATE_SHIFT_M,
    TOLERANCE_M,
    VERIFICATIONS,
    ResearchMode,
    VerificationRule,
    research_mode,
    verification_rule,
)

if TYPE_CHECKING:  # the result types of higher layers, named in annotations only (docs/design/layout.md)
    from .ambiguity import PairAmbiguity
    from .consensus import AssemblyReport
    from .verify import Verification

AMBIGUITY_MARGIN = 0.05  # mean ν by which the chosen order must beat an accepted order that places a map elsewhere
DEFAULT_METHOD = "fast"  # the search method of a merge and of merger.align: the branch and bound (exact)
DEFAULT_REFINE = True  # merges and merger.align refine below the search grid (RotationProblem's own: False)

Placement = tuple[float, tuple[float, float]]  # (θ, t) onto a frame: x_f = c_f + t + R(θ)(x − c)
ORIGIN: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class MergeParams:
    """Parameters of a merge cycle.

    roi_m : side of the square region of interest around the center, metres.
    measure : similarity maximized by the search ("similarity", "birk_carpin" or "ncc").
    method : search method name (see :data:`merger.search.SEARCH_METHODS`).
    verification : "whole_map" — ω̃ on whole maps with ``nu_min`` and ``min_support`` (the similarity
        method); "roi_score" — every alignment's ROI score ≥ ``score_min`` (the thesis's
        cross-correlation method, which had only a threshold on the correlation coefficient); "contrast" —
        for maps from independent runs (real maps): every pair's whole-map fit within ``tolerance_m`` must
        stand at least ``contrast_min`` times above its best rival placement at least 10° away, on at
        least ``min_support`` occupied cells (:mod:`merger.team.evidence`; measured on real maps in
        docs/merging-real-maps.md). Orders are still ranked by Σν. "auto" (default) — a pair passes when
        either "whole_map" or "contrast" passes it: the thesis's rule on maps that agree cell by cell (the
        simulator's), the contrast rule on maps from independent runs (:func:`merger.team.verify.check_pair`;
        derived in docs/merging-real-maps.md).
    refine_whole : the placement of a map the contrast rule accepted is refined on the whole maps (the
        contrast rule's fit, :func:`refine_chosen`; translations only with a window) and the merged map
        drawn there; the search's placement is kept beside it (``OrderResult.search_theta_deg``,
        ``search_translation_m``). A pair ν accepted keeps the search's placement. Off: the merged map at
        the search's placement (the thesis).
    research : "on_change" (default) — a pair (tree) or the team's hypothesis (orders) that holds an accepted
        answer is re-verified at each new map version by an exact local search about it and searched
        globally only when that fails, its ν falls more than ``research_drop`` below the last global
        search's, a map's ROI changed by more than ``research_change`` (fraction of known cells; not the team's ring) since then,
        or ``research_period_s`` passed (:mod:`merger.team.track`); "every_version" — every map version is
        searched globally (the thesis's behaviour).
    ambiguity_margin : with it (default: 0.05 with a window, 0 without), a cycle in which another accepted
        order places some map more than 10° or 0.2 m away from the chosen order's placement is rejected as
        ambiguous unless the chosen order's mean ν exceeds that order's by at least this margin. A wider
        search finds more spurious peaks: on the point-symmetric scene 1, a half turn plus a translation
        of ~0.35 m passes whole-map verification (ν ≈ 0.7) beside the correct order (ν ≈ 0.78).
    window_m : translation window, metres: every pair is searched over rotations and translations
        within ±window_m on each axis (:mod:`merger.search`), for centers known only roughly; 0 is the
        thesis's rotation-only search. At most a quarter of ``roi_m``.
    refine : refine θ and t below the search grid (:func:`merger.search.refine_alignment`); off
        reproduces the thesis's 0.1° grid answer exactly.
    roi_min_support : the search's support floor, cells: a placement whose ROI support agr̃ + dis is
        below it scores 0 (:class:`merger.search.RotationProblem`), so a wide window cannot find an
        optimum resting on a handful of cells (on sparse real maps with W ≥ 1.5 m, placements on 2–22
        cells scored ≈ 1 above the true one). 50 cells = 2.5 m of wall at 5 cm.
    combine_orders : the chosen placement is the mean of the accepted orders that agree with the
        highest-Σν order within 10° and 0.2 m on every map, when that mean passes whole-map verification
        (:func:`_combine`); off: the highest-Σν order's own placement (the thesis's rule). With the
        thesis's sparse maps (five scans per map) the Σν of a correct order and of one 2° off differed by
        less than ν can resolve on 200 cells, and the first of equal sums was sometimes the wrong one.
    teammate_radius_m : the teammates' body radius, metres (``strategy: tree``): a map whose trajectory
        circles the center has the occupied cells of the ring its team drives (its path's radii ± this
        radius + ``window_m``/2) left out of every pair's search and check (:mod:`merger.team.teammates`:
        robots across the circle see opposite faces of the same bodies); the merged map keeps them. 0 (the
        default): off — in a bare hall the teammates are the only cue along the walls, and without them
        pairs slid along the walls (measured in docs/experiments.md).
    teammate_shift_m : how far each occupied cell on the ring its team drives (the map's path radii ± twice
        this + ``window_m``/2) is moved along the line of sight from the map's robot, metres (``strategy:
        tree``; :func:`merger.team.teammates.teammates_centred`): a teammate's face, as this robot sees it,
        moved towards the teammate's centre line, so that robots across the circle and beside a teammate
        place its body alike. Uncorrected, the faces seen from across the circle (the inner side) and from
        beside it (the flank) make every pair across the circle pull its maps towards each other, and the
        whole team's placement shrinks towards the center — consistent around every cycle, so no check of
        the team sees it (12 robots in an L room: each map 3–7 cm inwards, pairs across 10–16 cm off). The
        searches, local searches and checks use the moved cells; the merged map keeps the maps as given; a
        map without a path, or whose path is no circle about the center, is left as it is. Not used when
        ``teammate_radius_m`` leaves the ring out. 0.12 by default (about two thirds of the bench's 0.18 m
        bodies; a TurtleBot3 Burger's 0.105 m radius calls for less); 0: off. Measured at 4 to 32 robots in
        docs/experiments.md: the 12-robot L room's false merges neither gross nor drift-limited 17/18/22 →
        10/5/6 (30 s, 3 seeds), the bare hall's 12 robots 25 gross → 0, the quality halls unchanged.
    """

    roi_m: float = DEFAULT_ROI_M
    measure: str = DEFAULT_MEASURE
    method: str = DEFAULT_METHOD
    verification: str = "auto"
    nu_min: float = 0.5
    min_support: int = 200
    score_min: float = 0.5
    window_m: float = DEFAULT_WINDOW_M
    refine: bool = DEFAULT_REFINE
    ambiguity_margin: float | None = None
    combine_orders: bool = True
    roi_min_support: int = ROI_MIN_SUPPORT
    tolerance_m: float = TOLERANCE_M
    contrast_min: float = CONTRAST_MIN
    refine_whole: bool = True
    research: str = RESEARCH_DEFAULT
    research_period_s: float = RESEARCH_PERIOD_S
    research_change: float = RESEARCH_CHANGE
    research_drop: float = RESEARCH_DROP
    teammate_radius_m: float = TEAMMATE_RADIUS_M
    teammate_shift_m: float = TEAMMATE_SHIFT_M

    @property
    def margin(self) -> float:
        """The ambiguity margin in force: ``ambiguity_margin``, or by default 0.05 with a translation
        window and 0 without one (the thesis's rule: the highest Σν wins)."""
        if self.ambiguity_margin is not None:
            return float(self.ambiguity_margin)
        return AMBIGUITY_MARGIN if self.window_m > 0 else 0.0

    @property
    def verification_rule(self) -> VerificationRule:
        """The verification rule in force: ``verification``'s object (:mod:`merger.team.defaults`)."""
        return verification_rule(self.verification)

    @property
    def research_mode(self) -> ResearchMode:
        """The research mode in force: ``research``'s object (:mod:`merger.team.defaults`)."""
        return research_mode(self.research)

    def __post_init__(self) -> None:
        for name, rule in RULES.items():  # every setting's one rule, named by its field
            rule(getattr(self, name), name)
        check_window(self.window_m, self.roi_m)  # the one rule between two settings


# --- the settings' rules ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class Rule:
    """One setting's rule: ``rule(value, key)`` returns the value (a number as a float, a count as an int)
    when ``accepts(value)``, else raises :class:`~merger.settings.SettingError` ``key`` + " must be
    <expected>, got <value>". ``expected`` is the range in words (a callable: words read when asked, e.g.
    the registered search methods); ``why`` where the range comes from (both printed by the scenario
    reference and the command line's help)."""

    words: str | Callable[[], str]
    accepts: Callable[[object], bool]
    convert: Callable = lambda v: v  # the value as it came
    why: str = ""
    own: Callable | None = None  # the search's own rule ``own(value, key)``, with its own words (_of)

    @property
    def expected(self) -> str:
        return self.words() if callable(self.words) else self.words

    def __call__(self, value, key: str):
        if self.own is not None:
            return self.own(value, key)
        if not self.accepts(value):
            raise SettingError(key, f" must be {self.expected}, got {value!r}")
        return self.convert(value)


def _real(v) -> bool:
    return not isinstance(v, (bool, np.bool_)) and isinstance(v, (int, float, np.integer, np.floating)) \
        and math.isfinite(v)


def number(lo: float | None = None, hi: float | None = None, *, open_lo: bool = False, why: str = "") -> Rule:
    """A finite number (not a bool) in [lo, hi] (``open_lo``: (lo, hi]; None: unbounded on that side)."""
    left = f"{'(' if open_lo else '['}{lo:g}" if lo is not None else None
    words = (f"a number in {left}, {hi:g}]" if lo is not None and hi is not None else
             f"a finite number {'>' if open_lo else '>='} {lo:g}" if lo is not None else
             f"a finite number <= {hi:g}" if hi is not None else "a finite number")

    def accepts(v) -> bool:
        return _real(v) and (lo is None or (v > lo if open_lo else v >= lo)) and (hi is None or v <= hi)
    return Rule(words, accepts, float, why)


def count(lo: int = 0, why: str = "") -> Rule:
    """A whole number (an int or a numpy integer, not a bool) ≥ ``lo``."""
    return Rule(f"an integer >= {lo}", lambda v: not isinstance(v, (bool, np.bool_))
                and isinstance(v, (int, np.integer)) and v >= lo, int, why)


def one_of(options, why: str = "") -> Rule:
    """One of ``options`` (strings)."""
    return Rule("one of " + ", ".join(map(repr, options)), lambda v: isinstance(v, str) and v in options, str, why)


def optional(rule: Rule) -> Rule:
    """None (YAML null) or what ``rule`` accepts."""
    return Rule(f"null or {rule.expected}", lambda v: v is None or rule.accepts(v),
                lambda v: None if v is None else rule.convert(v), rule.why)


def _of(check, words, why: str = "") -> Rule:
    """A rule that is one of the search's own (``check(value, key)``, :mod:`merger.settings`)."""
    def accepts(v) -> bool:
        try:
            check(v, "")
        except ValueError:
            return False
        return True

    return Rule(words, accepts, why=why, own=check)


FLAG = Rule("true or false", lambda v: isinstance(v, (bool, np.bool_)), bool)
POSITIVE = number(0.0, open_lo=True)
FRACTION = number(0.0, 1.0)

# Every MergeParams setting's one rule (a setting added to MergeParams without one fails the import). The
# ranges are the algorithm's: ν is ω̃ = agr̃ / (agr̃ + dis) on the whole maps whatever the search's measure
# (merger.team.verify), so a threshold outside [0, 1] accepts or refuses everything; the ROI score of the
# roi_score rule is the measure's, ω̃ and ω in [0, 1], NCC in [-1, 1]; a drop of ν is at most 2.
RULES: dict[str, Rule] = {
    "roi_m": _of(lambda v, key: check_roi(v, key=key), "a number of metres > 0"),
    "measure": _of(check_measure, MEASURE_EXPECTED),
    "method": Rule(lambda: "a registered search method: one of " + ", ".join(map(repr, sorted(SEARCH_METHODS))),
                   lambda v: isinstance(v, str) and v in SEARCH_METHODS, str),  # read when checked: plug-ins
    "verification": one_of(VERIFICATIONS),
    "nu_min": number(0.0, 1.0, why="ν is ω̃ = agr̃ / (agr̃ + dis) of the whole maps, whatever the search's "
                     "measure"),
    "min_support": count(0),
    "score_min": number(-1.0, 1.0, why="the roi_score rule's threshold on the search's score: ω̃ and ω lie "
                        "in [0, 1], NCC in [-1, 1]"),
    "window_m": _of(lambda v, key: check_window(v, None, key),
                    "a number of metres >= 0, at most a quarter of roi_m"),
    "refine": FLAG,
    "ambiguity_margin": optional(FRACTION),
    "combine_orders": FLAG,
    "roi_min_support": _of(check_floor, FLOOR_EXPECTED),
    "tolerance_m": POSITIVE,
    "contrast_min": POSITIVE,
    "refine_whole": FLAG,
    "research": one_of(RESEARCH_MODES),
    "research_period_s": number(0.0, 1e6, open_lo=True, why="a staleness bound is a positive time (every version "
                                "searched globally is research every_version)"),
    "research_change": FRACTION,
    "research_drop": number(0.0, 2.0, why="the fall of a score in [-1, 1]"),
    "teammate_radius_m": number(0.0, 10.0, why="a robot's body radius (0: off)"),
    "teammate_shift_m": number(0.0, 1.0, why="a distance within a robot's body (0: off)"),
}
if list(RULES) != [f.name for f in fields(MergeParams)]:
    raise ImportError(f"MergeParams: rules for {list(RULES)}, settings {[f.name for f in fields(MergeParams)]}")


@dataclass(frozen=True, eq=False)
class MapInput:
    """A map to merge: its owner's name, the grid (in the owner's frame) and the center in that frame.

    ``version`` (optional, hashable; e.g. the map message's stamp) identifies this grid, center and
    trajectory among the owner's maps: with versions, :func:`merge_team` can reuse a pair alignment of unchanged maps
    from an earlier cycle (its ``reuse`` argument).

    ``trajectory`` (optional): the owner robot's path in the map's frame, rows (t, x, y) by time, t in
    seconds on a clock the team shares (a ROS robot's base_link in its map frame, from tf). It is physical
    evidence no cycle check gives: a team placement that puts two robots in one place at the same time
    is refused (:mod:`merger.team.consensus`). Maps of independent runs have no common instants: no test."""

    name: str
    grid: OccupancyGrid
    center: tuple[float, float]
    version: object = None
    trajectory: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        try:
            ok = len(self.center) == 2 and all(math.isfinite(float(v)) for v in self.center)
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ValueError(f"map {self.name!r}: center must be two finite numbers (x, y), got {self.center!r}")
        if self.trajectory is not None:
            tr = np.asarray(self.trajectory, np.float64)
            if tr.ndim != 2 or tr.shape[1] != 3 or not np.isfinite(tr).all() or (np.diff(tr[:, 0]) < 0).any():
                raise ValueError(f"map {self.name!r}: trajectory must be rows (t, x, y) of finite numbers by time, "
                                 f"got shape {tr.shape}")
            object.__setattr__(self, "trajectory", tr)


@dataclass(frozen=True, eq=False)
class OrderResult:
    """One merge order's hypothesis and its verification.

    theta_deg : per map name, the rotation onto map 0's frame (map 0 itself: 0).
    translation_m : per map name, the translation t onto map 0's frame: x_0 = c_0 + t + R(θ)(x − c)
        (all (0, 0) for a rotation-only search).
    steps : (moving map name, Alignment) in the order they were searched; angles there are onto the
        superposition's frame (the order's first map).
    nu : per pair "A|B", the whole-map ω̃ (or the ROI score with verification "roi_score").
    """

    order: tuple[str, ...]
    theta_deg: dict[str, float]
    steps: tuple[tuple[str, Alignment], ...]
    checks: dict[str, Verification]
    accepted: bool
    reason: str
    translation_m: dict[str, tuple[float, float]] = field(default_factory=dict)
    combined: tuple[tuple[str, ...], ...] = ()  # the accepted orders whose mean placement this is (_combine)
    # the search's placement when theta_deg / translation_m are its whole-map refinement (refine_chosen)
    search_theta_deg: dict[str, float] = field(default_factory=dict)
    search_translation_m: dict[str, tuple[float, float]] = field(default_factory=dict)

    def translation(self, name: str) -> tuple[float, float]:
        return self.translation_m.get(name, (0.0, 0.0))

    @property
    def nu(self) -> dict[str, float]:
        return {k: v.nu for k, v in self.checks.items()}

    @property
    def nu_sum(self) -> float:
        return float(sum(v.nu for v in self.checks.values()))

    def angle_errors_deg(self, truth_deg: dict[str, float]) -> dict[str, float]:
        """|wrap(θ − θ*)| per map against ground-truth rotations onto map 0's frame."""
        return {k: abs(angle_diff_deg(self.theta_deg[k], truth_deg[k])) for k in self.theta_deg}

    def to_dict(self) -> dict:
        return {
            "order": list(self.order), "theta_deg": dict(self.theta_deg),
            "translation_m": {k: list(self.translation(k)) for k in self.theta_deg}, "accepted": self.accepted,
            "reason": self.reason, "nu": self.nu, "nu_sum": self.nu_sum,
            "support": {k: v.support for k, v in self.checks.items()},
            "checks": {k: v.to_dict() for k, v in self.checks.items()},
            "steps": [{"moving": n, **a.to_dict()} for n, a in self.steps],
            "combined": [list(o) for o in self.combined],
            "search_theta_deg": dict(self.search_theta_deg),
            "search_translation_m": {k: list(v) for k, v in self.search_translation_m.items()},
        }


@dataclass(frozen=True, eq=False)
class TeamMergeResult:
    """All orders of one merge cycle, the chosen one (if any) and the merged map in map 0's frame.

    ``merged`` and ``layers`` may be given as a function (``fuse``) instead: the merged map is then built
    when it is first read (the tree strategy: a robot of a simulation merges several times a second and its
    merged map is drawn once per recording period; its placement, the cycle's decision, never reads it).
    ``wall_ms`` is the cycle's time without it; :attr:`fuse_ms` the building's, once it is built. ``cpu_ms``:
    the CPU time of the cycle's own computations on every thread (:class:`merger.team.pool.CpuClock`; None:
    not measured)."""

    frame: str
    orders: tuple[OrderResult, ...]
    chosen: OrderResult | None
    merged_map: OccupancyGrid | None = field(repr=False)
    merged_layers: dict[str, OccupancyGrid] = field(repr=False)
    wall_ms: float = 0.0
    ambiguity: str = ""  # why a cycle whose best order passed verification was not accepted
    ambiguous: tuple[PairAmbiguity, ...] = ()  # the cycle's ambiguous pairs (:mod:`merger.team.ambiguity`)
    charged_ms: float = 0.0  # the computing time of results taken from a shared memo (:mod:`merger.team.memo`)
    assembly: AssemblyReport | None = None  # the tree strategy's consensus assembly (:mod:`merger.team.consensus`)
    fuse: Callable[[], tuple[OccupancyGrid, dict[str, OccupancyGrid]]] | None = field(default=None, repr=False)
    fuse_ms: float = 0.0
    cpu_ms: float | None = None

    def _fused(self) -> None:
        fuse = self.fuse
        if fuse is not None:  # built once (two threads reading it at once build the same map twice)
            t0 = time.perf_counter()
            merged, layers = fuse()
            object.__setattr__(self, "merged_map", merged)
            object.__setattr__(self, "merged_layers", layers)
            object.__setattr__(self, "fuse_ms", (time.perf_counter() - t0) * 1e3)
            object.__setattr__(self, "fuse", None)

    @property
    def merged(self) -> OccupancyGrid | None:
        """The merged map in map 0's frame (None: the cycle was not accepted)."""
        self._fused()
        return self.merged_map

    @property
    def layers(self) -> dict[str, OccupancyGrid]:
        """Each placed map on the merged map's canvas, by name ({}: not accepted)."""
        self._fused()
        return self.merged_layers

    @property
    def cost_ms(self) -> float:
        """What the cycle costs a robot computing alone: the CPU time of its own computations (its wall time
        when not measured) and that of the shared results it took (:mod:`merger.team.memo`). Its wall time
        counts the other robots' cycles running beside it on the same cores; its CPU time does not."""
        return (self.wall_ms if self.cpu_ms is None else self.cpu_ms) + self.charged_ms

    @property
    def reason(self) -> str:
        """Why the cycle was not accepted ("" when it was)."""
        if self.accepted:
            return ""
        return self.ambiguity or self.top.reason

    @property
    def accepted(self) -> bool:
        return self.chosen is not None

    @property
    def rule(self) -> str:
        """The rule that decided the cycle: "verification" (accepted, or the best order failed it — its
        ``reason`` names the check and its figures), "no_evidence" (a search found nothing to align),
        "ambiguity" (another accepted order places a map elsewhere) or "guard" (a search found a better
        alignment beyond its translation window)."""
        if self.accepted:
            return "verification"
        if self.ambiguity:
            return "guard" if self.ambiguity.startswith("beyond the window") else "ambiguity"
        if self.top.reason.startswith("no evidence"):
            return "no_evidence"
        return "verification"

    @property
    def top(self) -> OrderResult:
        """The best hypothesis of the cycle, accepted or not (highest Σν)."""
        return self.chosen or max(self.orders, key=lambda o: o.nu_sum)

    @property
    def rejected(self) -> tuple[OrderResult, ...]:
        return tuple(o for o in self.orders if not o.accepted)

    def to_dict(self) -> dict:
        return {"frame": self.frame, "accepted": self.accepted, "verdict": "accepted" if self.accepted else "rejected",
                "rule": self.rule, "reason": self.reason, "wall_ms": self.wall_ms,
                "cpu_ms": self.cpu_ms, "charged_ms": self.charged_ms, "cost_ms": self.cost_ms,
                "ambiguity": self.ambiguity, "ambiguous": [a.to_dict() for a in self.ambiguous],
                "chosen": self.chosen.to_dict() if self.chosen else None,
                "assembly": self.assembly.to_dict() if self.assembly is not None else None,
                "orders": [o.to_dict() for o in self.orders]}
