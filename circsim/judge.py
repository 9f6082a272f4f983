"""Judging an alignment against ground truth: per map, its angle error and translation error, and whether
the hypothesis is correct.

An alignment of map j onto map i is x_i = c_i + t + R(θ)(x_j − c_j); its angle error is
|wrap(θ − θ*_ij)| and its translation error the Euclidean |t − t*_ij| in metres, with
t*_ij = R(θ*_ij)·e_j − e_i (e_k: robot k's center error, see :func:`circsim.sim.truth_translation`). A
rotation-only search (``window_m: 0``) finds t = 0, so its translation error is |t*|: the misplacement
that a wrong center causes. A hypothesis is correct when every angle error is ≤ ``correct_tol_deg`` and
every translation error ≤ ``correct_tol_m``, allowing :data:`JUDGE_EPS_DEG` / :data:`JUDGE_EPS_M` of
floating-point noise (an answer on the search's lattice exactly at the tolerance counts as within it).

One judge for every place that scores a merge: the run (:mod:`circsim.sim`, its metrics
:mod:`circsim.metrics`), ``circsim score`` (:mod:`circsim.score`) and the offline experiment
(:mod:`circsim.experiments.offline`), so that they cannot disagree on what is correct.
"""

from __future__ import annotations

import math

from merger.search import angle_diff_deg

JUDGE_EPS_DEG = 1e-9
JUDGE_EPS_M = 1e-9


def judge(theta_deg: dict[str, float], truth_deg: dict[str, float], tol_deg: float):
    """Angle errors per map and whether every one is within ``tol_deg``.

    The comparison allows 1e-9° of floating-point noise: an angle on the search's 0.1° lattice that is
    exactly ``tol_deg`` from the truth (e.g. 2.0000000000000284°) counts as within it."""
    errors = {k: abs(float(angle_diff_deg(theta_deg[k], truth_deg[k]))) for k in theta_deg}
    return errors, all(e <= tol_deg + JUDGE_EPS_DEG for e in errors.values())


def judge_translation(translation_m: dict[str, tuple[float, float]], truth_m: dict[str, tuple[float, float]],
                      tol_m: float):
    """Translation errors |t − t*| (Euclidean, metres) per map and whether every one is within ``tol_m``.

    Like :func:`judge`, 1e-9 m of floating-point noise is allowed: a translation on the search's cell
    lattice exactly ``tol_m`` from the truth counts as within it."""
    errors = {k: math.hypot(float(translation_m[k][0]) - float(truth_m[k][0]),
                            float(translation_m[k][1]) - float(truth_m[k][1])) for k in translation_m}
    return errors, all(e <= tol_m + JUDGE_EPS_M for e in errors.values())


def judge_placement(theta_deg: dict[str, float], translation_m: dict[str, tuple[float, float]],
                    truth_deg: dict[str, float], truth_m: dict[str, tuple[float, float]], tol_deg: float,
                    tol_m: float):
    """Angle errors, translation errors and whether the hypothesis is correct: every angle error
    ≤ ``tol_deg`` and every translation error ≤ ``tol_m`` (:func:`judge`, :func:`judge_translation`).
    A map missing from ``translation_m`` has t = (0, 0) (a rotation-only search)."""
    angle_errors, angles_ok = judge(theta_deg, truth_deg, tol_deg)
    t = {k: tuple(translation_m.get(k, (0.0, 0.0))) for k in theta_deg}
    t_errors, t_ok = judge_translation(t, truth_m, tol_m)
    return angle_errors, t_errors, angles_ok and t_ok
