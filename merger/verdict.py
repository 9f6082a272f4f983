"""The words of a merge's verdict: the rule that decided and its figures, as ``merger merge`` prints them
and :class:`merger.merge.MergeResult` carries them (``rule``, ``reason``).

A cycle accepted is accepted by the verification rule that passed its pairs: "contrast" (the pair's
whole-map fit against its best rival, :mod:`merger.team.evidence`) or "whole-map ν" (the thesis's rule),
with each pair's figures (:func:`evidence_text`). A cycle refused names the rule that refused it
("verification", "no evidence", "the ambiguity rule", "the guard beyond the window": :data:`RULE_NAMES`
of :attr:`merger.team.params.TeamMergeResult.rule`) and its figures (:func:`refusal`).
"""

from __future__ import annotations

import math

RULE_NAMES = {"verification": "verification", "no_evidence": "no evidence", "ambiguity": "the ambiguity rule",
              "guard": "the guard beyond the window"}
ALGORITHM_RULE = "the algorithm's own rule (merger.algorithms)"


def evidence_text(v, label: str = "") -> str:
    """The figures of the rule that verified a pair, read from its :class:`~merger.team.verify.Verification`:
    the contrast, its fit, rival and support when the contrast rule decided (ν then only for the record),
    else ν and its support."""
    name = f"{label} " if label else ""
    k = v.contrast
    if k is not None and math.isnan(k.best):  # refused on its support before any fit (evidence.contrast)
        return f"{name}{k.support} cells under the contrast rule; ν {v.nu:.2f}"
    if k is not None:
        rival = (f"rival {k.rival:.3f} at {k.rival_at[0]:+.0f}°" if k.rival > 0 and math.isfinite(k.rival_at[0])
                 else "rival not computed (the fit's angle already refuses)" if math.isnan(k.rival) else "no rival")
        contrast = "–" if math.isnan(k.contrast) else f"{k.contrast:.2f}"
        return f"{name}contrast {contrast} (fit {k.best:.3f} vs {rival}, {k.support} cells; ν {v.nu:.2f})"
    return f"{name}ν {v.nu:.3f} ({v.support} cells)"


def rule_of(checks) -> str:
    """The verification rule the checks ran: "contrast" when they carry contrast evidence, else "whole-map ν"."""
    checks = list(checks)
    if not checks:
        return ALGORITHM_RULE
    return "contrast" if any(v.contrast is not None for v in checks) else "whole-map ν"


def refused_reason(res) -> str:
    """The figures of the rule that refused a cycle (its reason without the rule's own prefix)."""
    reason = res.reason
    for prefix in ("beyond the window: ", "ambiguous: "):
        reason = reason.removeprefix(prefix)
    return reason


def refusal(res) -> str:
    """The rule that refused a cycle and its figures: "the guard beyond the window: ..."."""
    return f"{RULE_NAMES[res.rule]}: {refused_reason(res)}"


def verdict_words(res) -> tuple[str, str]:
    """(rule, reason) of a :class:`~merger.team.params.TeamMergeResult`: the rule that accepted the chosen
    order and each pair's figures, or the rule that refused the cycle and its figures."""
    if res.chosen is not None:
        checks = res.chosen.checks
        return rule_of(checks.values()), "; ".join(evidence_text(v, k) for k, v in checks.items())
    return RULE_NAMES[res.rule], refused_reason(res)
