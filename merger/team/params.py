"""The team's parameter set and value types: :class:`MergeParams` (every setting of a merge cycle, with
its one default and its one check), the maps to merge (:class:`MapInput`) and what a cycle answers
(:class:`OrderResult`, :class:`TeamMergeResult`, placements as :data:`Placement`).

Every strategy (:mod:`merger.team.orders`, :mod:`.tree`, :mod:`.follow`, :mod:`.shared`), the
simulation bench (its scenarios' ``merger`` section is these settings plus the bench's own:
:class:`circsim.config.scenario.MergerSettings`) and the command lines read them from here;
:mod:`merger.team.orders` re-exports them. The search's own settings (``roi_m``, ``window_m``) take their
default and their rule from :mod:`merger.search.problem` (``DEFAULT_ROI_M``, ``DEFAULT_WINDOW_M``,
:func:`~merger.search.problem.check_roi`, :func:`~merger.search.problem.check_window`), which
:class:`~merger.search.RotationProblem` shares.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..grid import OccupancyGrid
from ..search.problem import (
    DEFAULT_ROI_M,
    DEFAULT_WINDOW_M,
    ROI_MIN_SUPPORT,
    Alignment,
    angle_diff_deg,
    check_roi,
    check_window,
)
from .ambiguity import PairAmbiguity
from .evidence import CONTRAST_MIN, TOLERANCE_M
from .track import RESEARCH_CHANGE, RESEARCH_DEFAULT, RESEARCH_DROP, RESEARCH_MODES, RESEARCH_PERIOD_S
from .verify import Verification

VERIFICATIONS = ("auto", "whole_map", "roi_score", "contrast")
AMBIGUITY_MARGIN = 0.05  # mean ν by which the chosen order must beat an accepted order that places a map elsewhere

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
        search's, a map's ROI changed by more than ``research_change`` (fraction of known cells) since then,
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
    """

    roi_m: float = DEFAULT_ROI_M
    measure: str = "similarity"
    method: str = "fast"
    verification: str = "auto"
    nu_min: float = 0.5
    min_support: int = 200
    score_min: float = 0.5
    window_m: float = DEFAULT_WINDOW_M
    refine: bool = True
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

    @property
    def margin(self) -> float:
        """The ambiguity margin in force: ``ambiguity_margin``, or by default 0.05 with a translation
        window and 0 without one (the thesis's rule: the highest Σν wins)."""
        if self.ambiguity_margin is not None:
            return float(self.ambiguity_margin)
        return AMBIGUITY_MARGIN if self.window_m > 0 else 0.0

    def __post_init__(self) -> None:
        if self.verification not in VERIFICATIONS:
            raise ValueError(f"verification must be one of {VERIFICATIONS}, got {self.verification!r}")
        check_roi(self.roi_m)
        for name in ("nu_min", "score_min"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and -1.0 <= v <= 1.0):
                raise ValueError(f"{name} must be a finite number in [-1, 1], got {v!r}")
        if isinstance(self.min_support, bool) or not isinstance(self.min_support, (int, np.integer)) \
                or self.min_support < 0:
            raise ValueError(f"min_support must be an integer >= 0, got {self.min_support!r}")
        if isinstance(self.roi_min_support, bool) or not isinstance(self.roi_min_support, (int, np.integer)) \
                or self.roi_min_support < 0:
            raise ValueError(f"roi_min_support must be an integer >= 0, got {self.roi_min_support!r}")
        check_window(self.window_m, self.roi_m)
        for name, lo in (("tolerance_m", 0.0), ("contrast_min", 0.0)):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > lo):
                raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
        if self.research not in RESEARCH_MODES:
            raise ValueError(f"research must be one of {RESEARCH_MODES}, got {self.research!r}")
        for name, lo, hi in (("research_period_s", 0.0, 1e6), ("research_change", 0.0, 1.0),
                             ("research_drop", 0.0, 2.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float)) and math.isfinite(v) and lo <= v <= hi):
                raise ValueError(f"{name} must be a number in [{lo:g}, {hi:g}], got {v!r}")
        m = self.ambiguity_margin
        if m is not None and not (isinstance(m, (int, float)) and math.isfinite(m) and 0 <= m <= 1):
            raise ValueError(f"ambiguity_margin must be a number in [0, 1] (or None), got {m!r}")


@dataclass(frozen=True, eq=False)
class MapInput:
    """A map to merge: its owner's name, the grid (in the owner's frame) and the center in that frame.

    ``version`` (optional, hashable; e.g. the map message's stamp) identifies this grid and center among
    the owner's maps: with versions, :func:`merge_team` can reuse a pair alignment of unchanged maps
    from an earlier cycle (its ``reuse`` argument)."""

    name: str
    grid: OccupancyGrid
    center: tuple[float, float]
    version: object = None

    def __post_init__(self) -> None:
        try:
            ok = len(self.center) == 2 and all(math.isfinite(float(v)) for v in self.center)
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ValueError(f"map {self.name!r}: center must be two finite numbers (x, y), got {self.center!r}")


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
    """All orders of one merge cycle, the chosen one (if any) and the merged map in map 0's frame."""

    frame: str
    orders: tuple[OrderResult, ...]
    chosen: OrderResult | None
    merged: OccupancyGrid | None = field(repr=False)
    layers: dict[str, OccupancyGrid] = field(repr=False)
    wall_ms: float = 0.0
    ambiguity: str = ""  # why a cycle whose best order passed verification was not accepted
    ambiguous: tuple[PairAmbiguity, ...] = ()  # the cycle's ambiguous pairs (:mod:`merger.team.ambiguity`)
    charged_ms: float = 0.0  # the computing time of results taken from a shared memo (:mod:`merger.team.memo`)

    @property
    def cost_ms(self) -> float:
        """What the cycle costs a robot computing alone: its wall time and the time of the shared results
        it took (:mod:`merger.team.memo`)."""
        return self.wall_ms + self.charged_ms

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
                "charged_ms": self.charged_ms, "cost_ms": self.cost_ms,
                "ambiguity": self.ambiguity, "ambiguous": [a.to_dict() for a in self.ambiguous],
                "chosen": self.chosen.to_dict() if self.chosen else None,
                "orders": [o.to_dict() for o in self.orders]}
