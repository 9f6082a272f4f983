"""The fast rotation search: the reference's answer without 380 whole-ROI rotations.

:func:`fast_search` returns what :func:`merger.search.reference_search` returns — the thesis's search
(3.3.1): the best of the 360 coarse 1° angles (ties to the first), refined at 0.1° over ±1° (first
maximum) — in three steps:

1. **All angles, approximately** (:mod:`merger.polar`): both ROIs are max-pooled and resampled on rings
   about the shared center, where a rotation is a circular shift; the measure's counts for all 360
   angles are FFT cross-correlations along the angle axis (rings weighted by the area of a sample).
2. **A few coarse angles, exactly** (:class:`merger.sparse.SparseEvaluator`, which evaluates the
   measure exactly from the few cells that can change its counts): the approximate profile's peaks near
   its best, the angles of a flat top, and the best peak half a turn away (the thesis's typical false
   alignment, on symmetric scenes) are hill-climbed on the *exact* 1° profile. For ω̃, cheap upper
   bounds rule out most of them without evaluating them. The best exact local maximum is the
   reference's coarse angle — provided the approximation does not rank the true best peak far below
   the others, which the property tests and sweeps over generated scenes have not seen happen.
3. **The refinement, exactly**: the 21 angles ``coarse ± 1°`` at 0.1° (the same floats as the
   reference's), all evaluated exactly; the first maximum is θ, and its score and counts are the exact
   evaluator's, equal to ``problem.evaluate(θ)``.

The runner-up (best coarse angle ≥ 10° from θ) is evaluated exactly too, but found by a bounded search:
exact climbing from the far zone's edges (the main peak's flanks) and from the approximate profile's
best far peaks. Its value is an exact profile value, never above the reference's runner-up, and equal
to it on ~95% of generated cases (the misses are flat, noisy far zones whose maximum is elsewhere).
The returned ``profile`` is the approximate profile with the exact values substituted at every coarse
angle evaluated exactly before the search returned. All three measures (ω̃, Birk–Carpin ω, NCC) are
supported; Birk–Carpin's free/free count touches every free reference cell, so its exact evaluations
are the slowest. The usual case is one batch of exact evaluations (:meth:`SparseEvaluator.prepare`).

The runner-up and the counts are handed over deferred (:class:`merger.search.Alignment`): the first
read runs the runner-up search, or the free/free count at θ (ω̃ and NCC need only agr̃ and dis), on the
search's own evaluator. A merge cycle reads θ and the score only.
"""

from __future__ import annotations

import numpy as np

from .polar import approximate_profile
from .search import (
    RUNNER_UP_MIN_SEPARATION_DEG,
    Alignment,
    RotationProblem,
    angle_diff_deg,
    fine_angles,
    register_method,
    wrap_deg,
)
from .sparse import SparseEvaluator

MAX_CANDIDATES = 4  # approximate peaks looked at exactly
MAX_HIGH = {"birk_carpin": 24}  # angles of a flat approximate top looked at exactly (default 6)
MARGIN = 0.4  # a peak is a candidate when within MARGIN × (best − median) of the best approximate value
OPPOSITE_DEG = 20  # the best peak within this of the top + 180° is always a candidate
RUNNER_UP_CANDIDATES = 2
RUNNER_UP_HIGH = 0  # only the far zone's approximate peaks (its edges cover the main peak's flanks)
RUNNER_UP_STEPS = 2  # exact climbing moves allowed from each runner-up start
WINDOW = 2  # coarse angles either side of a candidate whose upper bounds decide if it can be skipped


class _Coarse:
    """Exact 1° profile values, computed on demand, with the reference's order (score, then first angle).

    Upper bounds (:meth:`SparseEvaluator.upper_bounds`, cheap) spare exact evaluations of angles that
    cannot win a comparison; exact evaluations are batched over all climbs at once.
    """

    def __init__(self, evaluator: SparseEvaluator) -> None:
        self.ev = evaluator
        self.values: dict[int, float] = {}
        self._ub: dict[int, float] = {}

    def need(self, idx) -> None:
        todo = [i for i in dict.fromkeys(int(i) % 360 for i in idx) if i not in self.values]
        if todo:
            self.values.update(zip(todo, self.ev.scores([float(i) for i in todo]).tolist(), strict=True))

    def bound(self, idx) -> None:
        todo = [i for i in dict.fromkeys(int(i) % 360 for i in idx) if i not in self._ub]
        if todo:
            self._ub.update(zip(todo, self.ev.upper_bounds([float(i) for i in todo]).tolist(), strict=True))

    def upper(self, i: int) -> float:
        i %= 360
        return self.values[i] if i in self.values else self._ub[i]

    def key(self, i: int):
        return (self.values[i % 360], -(i % 360))

    def best_of(self, starts, allowed: np.ndarray | None = None, steps: int = 360, window: int = WINDOW):
        """The best exact local maximum climbed from ``starts`` (within ``allowed``, a mask over 0..359,
        at most ``steps`` moves each). Climbs advance together, one batch of exact evaluations per step;
        a neighbour is evaluated only if its upper bound reaches the climb's current value, and a climb
        is dropped when nothing around it can reach the best value found so far."""
        ok = (lambda i: True) if allowed is None else (lambda i: bool(allowed[i % 360]))
        starts = [s % 360 for s in starts if ok(s)]
        if not starts:
            return None
        self.bound([s + d for s in starts for d in range(-window, window + 1) if ok(s + d)])
        known = [s for s in starts if s in self.values]
        best = max(known, key=self.key) if known else None

        def hopeless(s: int) -> bool:  # nothing around s can beat the best known start
            return best is not None and s != best and all(
                self.key(w) <= self.key(best) if w in self.values else self._ub[w] < self.values[best]
                for w in ((s + d) % 360 for d in range(-window, window + 1) if ok(s + d)))

        pos = [s for s in starts if not hopeless(s)]
        self.need(pos)
        done = []
        for _ in range(steps + 1):
            around = {p: [q % 360 for q in (p - 1, p + 1) if ok(q)] for p in pos}
            self.bound([q for qs in around.values() for q in qs])
            if best is not None:  # a climb below the best whose neighbours cannot reach it stops here
                pos = [p for p in pos if p == best or not (
                    self.values[p] < self.values[best] and all(self.upper(q) < self.values[best]
                                                               for q in around[p]))]
            if not pos:
                break
            contenders = {p: [q for q in around[p] if not self.upper(q) < self.values[p]] for p in pos}
            self.need([q for p in pos for q in contenders[p]])
            moved = []
            for p in pos:
                nxt = max([p] + contenders[p], key=self.key)
                if nxt == p:
                    done.append(p)
                    if best is None or self.key(p) > self.key(best):
                        best = p
                else:
                    moved.append(nxt)
            pos = list(dict.fromkeys(moved))
        done += pos  # out of steps: where the climbs stand
        return max(done + ([best] if best is not None else []), key=self.key)


def _local_maxima(profile: np.ndarray) -> np.ndarray:
    """Indices of circular local maxima (≥ left neighbour, > right neighbour), best first."""
    ext = np.concatenate([profile[-1:], profile, profile[:1]])
    idx = np.flatnonzero((profile >= ext[:-2]) & (profile > ext[2:]))
    return idx[np.argsort(-profile[idx], kind="stable")]


def _candidates(profile: np.ndarray, allowed=None, limit: int = MAX_CANDIDATES,
                high_limit: int = 6) -> list[int]:
    """The approximate profile's angles worth an exact look, most promising first: its local maxima
    close to the best one (at most ``limit``), and the angles close to the best value (at most
    ``high_limit``) — a flat top (Birk–Carpin's profiles) can hide the exact maximum a few degrees away."""
    idx = np.arange(profile.size) if allowed is None else np.flatnonzero(allowed)
    if idx.size == 0:
        return []
    vals = profile[idx]
    top = float(vals.max())
    tol = MARGIN * max(top - float(np.median(vals)), 1e-9)
    peaks = _local_maxima(profile)
    if allowed is not None:
        peaks = peaks[allowed[peaks]]
    high = idx[np.argsort(-vals, kind="stable")[:high_limit]]
    out = [int(i) for i in peaks[:limit] if profile[i] >= top - tol]
    out += [int(i) for i in high if profile[i] >= top - tol]
    return list(dict.fromkeys(out))


def fast_search(problem: RotationProblem) -> Alignment:
    """Rotation search returning the reference's answer (see the module documentation).

    Parameters
    ----------
    problem : the rotation problem (maps, centers, ROI side, measure).

    Returns
    -------
    Alignment with ``method="fast"``: ``theta_deg``, ``score`` and ``counts`` equal to the reference's
    (``score``/``counts`` are ``problem.evaluate(theta_deg)``); ``runner_up_deg``/``runner_up_score``
    are exact values at an exact local maximum of the far zone; ``profile`` is approximate except at
    the angles evaluated exactly.
    """
    ev = SparseEvaluator(problem)
    coarse = _Coarse(ev)
    approx = approximate_profile(problem)
    starts = _candidates(approx, high_limit=MAX_HIGH.get(problem.measure, 6))
    top = starts[0]
    # the thesis's typical false alignment is a half turn (symmetric scenes): its peak is always checked
    opposite = np.abs(angle_diff_deg(np.arange(360.0), top + 180.0)) <= OPPOSITE_DEG
    starts += [i for i in _candidates(approx, opposite, 1, 0)[:1] if i not in starts]
    # One batch for the usual case: the refinement around the best approximate peak (it holds the peak's
    # ±1° coarse neighbours) and bounds around the other candidates.
    ev.prepare(exact=[float(a) for a in fine_angles(float(top))],
               bounds=[float((s + d) % 360) for s in starts[1:] for d in range(-WINDOW, WINDOW + 1)])
    coarse.need([top - 1, top, top + 1])  # from the refinement batch, unless they wrap around 0°
    best = coarse.best_of(starts)
    fine = [float(a) for a in fine_angles(float(best))]
    values = ev.scores(fine)
    k = int(np.argmax(values))  # the first maximum, as the reference's strict '>' scan
    theta = wrap_deg(fine[k])
    profile = approx.copy()
    for i, v in coarse.values.items():
        profile[i] = v
    # the free/free count (Birk–Carpin's part of the counts) and the runner-up are computed if asked for
    return Alignment(theta, float(values[k]), lambda: ev.similarity(fine[k]).counts, problem.measure, "fast",
                     problem.roi_m, profile, lambda: _runner_up(coarse, approx, theta),
                     fine=(np.asarray(fine), np.asarray(values, np.float64)))


def _runner_up(coarse: _Coarse, approx: np.ndarray, theta: float) -> tuple[float, float]:
    """The best coarse angle at least 10° from θ: exact values, climbing within that zone from its edges
    (the main peak's flanks) and from the approximate profile's best far peaks."""
    angles = np.arange(360) * (360.0 / 360)
    far = np.abs(angle_diff_deg(angles, theta)) >= RUNNER_UP_MIN_SEPARATION_DEG
    if not far.any():
        return float("nan"), float("nan")
    edges = [i for i in np.flatnonzero(far).tolist() if not (far[i - 1] and far[(i + 1) % 360])]
    cands = _candidates(approx, far, RUNNER_UP_CANDIDATES, RUNNER_UP_HIGH)
    starts = list(dict.fromkeys(edges + cands))
    # one batch: the starts and their neighbours exactly (the far peaks), bounds one step further out
    coarse.ev.prepare(exact=[float((i + d) % 360) for i in cands[:1] for d in (-1, 0, 1)]
                      + [float(i % 360) for i in edges],
                      bounds=[float((i + d) % 360) for i in starts for d in (-2, -1, 1, 2)])
    r = coarse.best_of(starts, far, RUNNER_UP_STEPS, window=1)
    return float(angles[r]), coarse.values[r]


register_method("fast", fast_search)
