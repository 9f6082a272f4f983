"""Ambiguous pairs: a pair's best alignment and its runner-up score alike (issue 10, item 5).

A search answers the best (θ, t) on the region of interest; its runner-up (:attr:`Alignment.runner_up`,
the best coarse angle more than 10° away) is a rival, and so, with a translation window, is the best
placement at the same coarse angle more than 0.2 m away (:func:`shift_rival`); the higher-scoring of
the two is the pair's runner-up. In a point-symmetric neighbourhood of the center
the two peaks are the truth and its half turn, and the ROI cannot tell them apart. A pair is
*ambiguous* when the runner-up's exact score (:func:`rival`: the runner-up's best translation in the
window and its fine angle) is within the margin of the best's score. Whole-map evidence then decides
(:func:`resolve`): ν of the pair under both hypotheses; the one whose ν exceeds the other's by at
least the margin is used (it may be the runner-up: the ROI's best is then the false one), and when
neither does, the pair is not used — the orders strategy refuses an order that searched it, the tree
drops the edge. The margin is :attr:`merger.team.orders.MergeParams.margin` (0.05 with a window, 0 — the rule
off, the thesis's behaviour — without one), in the same ω̃ units for the ROI scores and for ν.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .. import caches
from ..search import (
    RUNNER_UP_MIN_SEPARATION_DEG,
    Alignment,
    BeyondQuery,
    RotationProblem,
    angle_diff_deg,
    beyond_window,
    exact_runner_up,
    fine_angles,
    reference_beyond,
    refine_alignment,
    searcher_for,
    wrap_deg,
)
from ..search.searcher import COARSE
from .verify import Verification

RIVAL_SHIFT_M = 0.2  # a translation rival lies more than this from the best (merger.team.orders.AMBIGUOUS_M)
PREFILTER_SLACK = 0.05  # the profile's runner-up score can be approximate (the fast search's polar
# stage): a pair is examined exactly when that score is within margin + this of the best
RIVAL_BUDGET = 6000  # regions the runner-up search may bound (deterministic: a count, not a time)
RIVAL_SPAN_DEG = 2  # the exact runner-up is the best coarse angle within ± this of the profile's

VERDICTS = ("best", "runner_up", "unresolved")


@dataclass(frozen=True)
class Hypothesis:
    """One placement of the moving map onto the reference: x_ref = c_ref + t + R(θ)(x − c), its ROI
    score and its whole-map ν (with the verification's support)."""

    theta_deg: float
    translation_m: tuple[float, float]
    score: float
    nu: float
    support: int
    passed: bool

    def to_dict(self) -> dict:
        return {"theta_deg": self.theta_deg, "translation_m": list(self.translation_m), "score": self.score,
                "nu": self.nu, "support": self.support, "passed": self.passed}


@dataclass(frozen=True)
class PairAmbiguity:
    """An ambiguous pair and what whole-map evidence made of it.

    ref, moving : the pair (``ref`` may be a superposition, named "A+B").
    best, runner_up : the two hypotheses (angles more than 10° apart, ROI scores within ``margin``).
    verdict : "best" or "runner_up" — ν of that hypothesis exceeds the other's by at least ``margin``,
        and it is the pair's alignment; "unresolved" — the pair is not used.
    """

    ref: str
    moving: str
    best: Hypothesis
    runner_up: Hypothesis
    margin: float
    verdict: str

    ambiguous = True

    @property
    def used(self) -> bool:
        return self.verdict != "unresolved"

    @property
    def chosen(self) -> Hypothesis | None:
        return {"best": self.best, "runner_up": self.runner_up}.get(self.verdict)

    def describe(self) -> str:
        b, r = self.best, self.runner_up
        head = (f"ambiguous pair {self.ref}←{self.moving}: θ {b.theta_deg:.1f}° (t ({b.translation_m[0]:+.2f}, "
                f"{b.translation_m[1]:+.2f}) m, score {b.score:.3f}, ν {b.nu:.3f}) vs θ {r.theta_deg:.1f}° "
                f"(t ({r.translation_m[0]:+.2f}, {r.translation_m[1]:+.2f}) m, score {r.score:.3f}, "
                f"ν {r.nu:.3f}), margin {self.margin:g}")
        if self.verdict == "unresolved":
            return head + ": whole-map evidence does not separate them, the pair is not used"
        return head + f": whole-map evidence chooses θ {self.chosen.theta_deg:.1f}°"

    @property
    def reason(self) -> str:
        """Why the pair is not used ("" when it is)."""
        return "" if self.used else self.describe()

    def to_dict(self) -> dict:
        return {"ref": self.ref, "moving": self.moving, "ambiguous": True, "verdict": self.verdict,
                "used": self.used, "margin": self.margin, "best": self.best.to_dict(),
                "runner_up": self.runner_up.to_dict(),
                "theta_deg": [self.best.theta_deg, self.runner_up.theta_deg]}


def rival(problem: RotationProblem, al: Alignment, margin: float, ev=None) -> Alignment | None:
    """The runner-up of ``al`` as an exact alignment when it scores within ``margin`` of ``al`` on the ROI
    (None otherwise, or when ``margin`` ≤ 0). A ``margin`` of 2 or more asks for the runner-up whatever
    its score (the pair's paths refuted ``al``: :func:`merger.team.tree.pair_result`).

    The profile's runner-up angle (coarse, possibly approximate) is re-evaluated exactly over every
    translation of the window at the coarse angles within ±2° of it (more than 10° from ``al``), then
    refined as the search refines its answer (0.1° over ±1°, then below the grid when the problem asks
    for it), so that both hypotheses are compared on equal terms. ``ev``: the
    :class:`merger.search.engine.Searcher` of ``problem`` (the search's own by default)."""
    if margin <= 0:
        return None
    if al.evidence.get("runner_up") == "exact":
        ru_deg, ru_score = al.runner_up
    else:  # the runner-up, looked for only where it could be a rival; exact unless the rivals are so many
        # and so close that RIVAL_BUDGET regions do not settle them (then the best found: a real placement)
        # the fast search's profile bounds every angle's values (Lemma 5): the search starts from it (Lemma 5c)
        env = al.profile if al.evidence.get("profile") == "upper_envelope" else None
        if margin >= 2.0:  # any runner-up, whatever its score (every measure lies in [-1, 1]): exactly, no budget
            ru_deg, ru_score = exact_runner_up(problem, al.theta_deg, envelope=env)
        else:
            ru_deg, ru_score = exact_runner_up(problem, al.theta_deg, floor=al.score - margin - PREFILTER_SLACK,
                                               budget=RIVAL_BUDGET, envelope=env)
    if not (math.isfinite(ru_deg) and math.isfinite(ru_score)) or al.score - ru_score >= margin + PREFILTER_SLACK:
        return None
    ev = ev if ev is not None else searcher_for(problem)
    k = problem.window_cells
    ts = [(a, b) for b in range(-k, k + 1) for a in range(-k, k + 1)]
    # the best coarse angle within ±RIVAL_SPAN_DEG of it, over the window: the first maximum in the
    # order of the angles, then of the translations (raster), exactly
    near = [float((round(ru_deg) + d) % 360) for d in range(-RIVAL_SPAN_DEG, RIVAL_SPAN_DEG + 1)]
    near = [th for th in near if abs(angle_diff_deg(th, al.theta_deg)) > RUNNER_UP_MIN_SEPARATION_DEG]
    top = ev.first_max(near, ts)
    if top is None:
        return None
    top_value, th_c, tc = top[0], near[top[1]], top[2]
    angles = np.array([a for a in fine_angles(th_c)
                       if abs(angle_diff_deg(float(a), al.theta_deg)) > RUNNER_UP_MIN_SEPARATION_DEG])
    return _exact_rival(problem, al, ev, angles, th_c, tc, top_value, margin)


def _exact_rival(problem: RotationProblem, al: Alignment, ev, angles, th_c: float, tc, top_value: float,
                 margin: float) -> Alignment | None:
    """A rival's fine angle at translation ``tc`` (the best of ``angles``, exactly), as an alignment like
    the search's — None when it scores ``margin`` or more below ``al``. ``th_c``, ``top_value``: its coarse
    angle and coarse score, for the guard beyond the window."""
    vals = ev.values_at_angles(angles, tc)
    kf = int(np.argmax(vals))
    theta, score = wrap_deg(float(angles[kf])), float(vals[kf])
    if al.score - score >= margin:
        return None
    # the guard beyond the window for the rival's own answer: a better alignment outside the window than
    # the rival refuses it as it would the best (the best may be the truth's peak cut by the window's
    # edge, and the rival the scene's half turn)
    out = Alignment(theta, score, ev.exact(float(angles[kf]), *tc)[1], al.measure, al.method, al.roi_m, al.profile,
                    (al.theta_deg, al.score), window_m=al.window_m, translation_m=problem.offset_m(*tc),
                    cells=tc, fine=(np.asarray(angles, np.float64), vals),
                    beyond_query=BeyondQuery(problem, top_value, (int(round(th_c)) % 360, tc),
                                             reference_beyond if al.method == "reference" else beyond_window),
                    evidence={"profile": al.evidence["profile"],  # the rival's runner-up is al itself
                              "runner_up": "exact"})
    return refine_alignment(problem, out) if problem.refine else out


def shift_rival(problem: RotationProblem, al: Alignment, margin: float, ev=None) -> Alignment | None:
    """The best alignment at the best's coarse angle whose translation lies more than 0.2 m from the
    best's, as an exact alignment, when it scores within ``margin`` of ``al`` on the ROI (None otherwise,
    without a window, or when ``margin`` ≤ 0).

    The angle rival (:func:`rival`) misses a rival at the same angle: with sparse maps and a window, a map
    shifted along its walls keeps a high ω̃ on fewer overlapping cells. On scene2-thesis (seed 1, centers
    off by 5 cm, W = 0.5 m) Lyon onto the superposition of its teammates scored 0.970 at t = (−0.48, +0.38) m,
    the window's edge, on 236 cells, and 0.941 at the truth (2, 1 cells) on 476; the shifted placement
    passed whole-map verification (ν 0.79 and 0.85) and was a false merge in three cycles. As a rival, the
    truth's whole-map ν decides. Its fine angle (0.1° over ±1°) and sub-cell refinement follow the search's.
    ``ev``: as for :func:`rival`."""
    k = problem.window_cells
    if margin <= 0 or k == 0:
        return None
    ev = ev if ev is not None else searcher_for(problem)
    a0 = problem.offset_m(*al.cells)
    far = [(a, b) for b in range(-k, k + 1) for a in range(-k, k + 1)
           if math.dist(problem.offset_m(a, b), a0) > RIVAL_SHIFT_M]
    if not far:
        return None
    th_c = float(int(round(al.theta_grid_deg)) % 360)  # the best's coarse angle
    top_value, _, tc = ev.first_max([th_c], far)  # the first maximum over ``far`` (raster order), exactly
    if al.score - top_value >= margin + PREFILTER_SLACK:
        return None
    return _exact_rival(problem, al, ev, fine_angles(th_c), th_c, tc, top_value, margin)


RIDGE_CELLS = 4  # a ridge's rival lies at least this many cells (Chebyshev) from the answer: 0.2 m at 5 cm


def ridge(problem: RotationProblem, al: Alignment, margin: float) -> str:
    """Why ``al`` lies on a translation ridge, or "": the best ROI score at its coarse angle ± 1° over the
    window's translations at least :data:`RIDGE_CELLS` from its own is within ``margin`` of its score (the
    same branch and bound; nothing without a window or a margin). Unlike :func:`shift_rival`, whole maps do
    not decide between the two: used when the team's ring is left out of the maps
    (:mod:`merger.team.teammates`), where what is left along two long walls is the same on the whole maps
    as on the ROI (a bare hall: 18 gross slides in 6 s, each 0.26–0.64 m along the walls, the angle exact)."""
    k = problem.window_cells
    if margin <= 0 or k == 0:
        return ""
    s = searcher_for(problem)
    a0, b0 = al.cells
    far = [(a, b) for b in range(-k, k + 1) for a in range(-k, k + 1)
           if max(abs(a - a0), abs(b - b0)) >= RIDGE_CELLS]
    if not far:
        return ""
    amask = np.zeros(360, bool)
    c = int(round(al.theta_grid_deg)) % 360
    amask[[(c - 1) % 360, c, (c + 1) % 360]] = True
    best, _ = s.run(COARSE, amask=amask, tmask=s.translation_mask(far))
    if best.value < al.score - margin:
        return ""
    (x, y), (x0, y0) = problem.offset_m(best.a, best.b), problem.offset_m(*al.cells)
    return (f"a translation ridge: ROI score {best.value:.3f} at ({x:+.2f}, {y:+.2f}) m against "
            f"{al.score:.3f} at ({x0:+.2f}, {y0:+.2f}) m")


def verdict(nu_best: float, nu_runner_up: float, margin: float) -> str:
    """Which hypothesis whole-map evidence separates from the other by at least ``margin``."""
    if nu_best - nu_runner_up >= margin:
        return "best"
    if nu_runner_up - nu_best >= margin:
        return "runner_up"
    return "unresolved"


def resolve(problem: RotationProblem, al: Alignment, margin: float, nu_of: Callable[[Alignment], Verification],
            ref: str, moving: str) -> tuple[Alignment, PairAmbiguity | None]:
    """The alignment to use for a pair and its ambiguity record (None: the pair is not ambiguous).

    ``nu_of`` verifies an alignment of the pair on the whole maps (the strategy's own rule). A pair whose
    two hypotheses both fail it is not reported (nothing to choose between). When the pair is ambiguous
    and unresolved the best alignment is returned with the record, whose ``used``
    is False: the caller does not use the pair."""
    # one searcher for both rivals: the search's own (its lattice tables), kept by merger.caches
    ev = searcher_for(problem) if margin > 0 else None
    rivals = [r for r in (rival(problem, al, margin, ev), shift_rival(problem, al, margin, ev)) if r is not None]
    # the search's frontier has been read (the runner-up starts from it): forgotten, or every result that
    # holds this alignment would keep it alive (its problem, for the guard: 338 MB in a 32-robot hall's 3 s)
    caches.drop_frontier(problem)
    if not rivals:
        return al, None
    riv = max(rivals, key=lambda r: r.score)  # the first (the angle rival) of equal scores
    vb, vr = nu_of(al), nu_of(riv)
    if not (vb.passed or vr.passed):  # neither is a merge: the pair fails on its own evidence
        return al, None
    hyp = [Hypothesis(a.theta_deg, tuple(a.translation_m), a.score, v.nu, v.support, v.passed)
           for a, v in ((al, vb), (riv, vr))]
    rec = PairAmbiguity(ref, moving, hyp[0], hyp[1], float(margin), verdict(vb.nu, vr.nu, margin))
    return (riv if rec.verdict == "runner_up" else al), rec
