"""The team's settings at the bottom of merger/team/: the defaults the lower modules read and each named
setting's table of choices (issue 45). It imports nothing of merger/team/; settings flow down from here.

* Defaults: :class:`~merger.team.params.MergeParams` takes its field defaults from here, and so do the
  modules that use them as their own: :mod:`.evidence` (``TOLERANCE_M``, ``CONTRAST_MIN``, the contrast
  rule's) and :mod:`.track` (``RESEARCH_*``, the tracker's); both re-export them under their old paths.
* Named choices: a setting whose value is a name (``verification``, ``research``) has one table here, one
  object per name holding what differs between the choices; the setting's allowed values are the table's keys
  (:data:`VERIFICATIONS`, :data:`RESEARCH_MODES`: MergeParams' rules, the scenario loader and the command
  lines offer them), and the code looks the object up once (``MergeParams.verification_rule``,
  ``.research_mode``) instead of comparing names. A new choice is one entry of its table (and the code its
  flags ask for). The other named settings' tables sit with their code: the strategies'
  (:data:`merger.team.online.STRATEGIES_BY_NAME`), the algorithms' (:data:`merger.algorithms.ALGORITHMS_BY_NAME`).
"""

from __future__ import annotations

from dataclasses import dataclass

# the contrast rule (merger.team.evidence)
TOLERANCE_M = 0.2  # the fit's tolerance: a cell d off a wall counts max(0, 1 − (d / D)²), D = TOLERANCE_M / resolution
CONTRAST_MIN = 1.5  # real maps: search answers 1.4–5.5, placements 20–180° off them ≤ 0.56 (docs/merging-real-maps.md)

# tracking (merger.team.track)
RESEARCH_DEFAULT = "on_change"
RESEARCH_PERIOD_S = 10.0  # Cartographer's global_constraint_search_after_n_seconds
RESEARCH_CHANGE = 0.1  # fraction of an ROI's known cells whose state changed since the last global search
RESEARCH_DROP = 0.1  # ν of the local answer may fall this far below the last global search's ν

# the team's ring (merger.team.teammates): off by default. On, 0.2 m (the bench's robots are 0.18 m; a
# TurtleBot3 Waffle's footprint 0.22 m, a Burger's 0.105 m): the 12-robot L room's false merges that are
# neither gross nor drift-limited fell from 17-22 to 0-4 a minute, but in a bare hall (generated plan 28) the
# teammates were the only cue along the walls, and without them the pairs placed 18 maps grossly in 6 s (refused
# since as translation ridges: no merge there in 8 s), and newuser5's seed 2 merged 3.1 s later
TEAMMATE_RADIUS_M = 0.0
# the faces moved to the teammates' centre lines (merger.team.teammates.teammates_centred): on by default since
# the seventh pass of issue 43 (docs/experiments.md), once a pair chosen over its rival no longer joins parts
# of a team alone (merger.team.consensus; the four-robot bare hall's half turns). Same invocation, defaults
# before -> after, gross/other/drift-limited false merges: lroom12 30 s seeds 1-3 0/17/23, 0/18/21, 0/22/59 ->
# 0/10/3, 0/5/15, 0/6/26; bare hall (plan 28, 10 s) 4/8/12 robots 0/12/5, 0/7/94, 25/33/130 -> 0/17/1, 0/3/60,
# 0/20/176; hall4/hall8/newuser5 60 s x 3 seeds and hall16 30 s: 0 false either way
TEAMMATE_SHIFT_M = 0.12


@dataclass(frozen=True)
class VerificationRule:
    """A verification rule (``MergeParams.verification``): how a hypothesis's pairs are checked.

    whole_maps : the pairs are checked on the whole maps placed (:func:`merger.team.verify.check_pair`), and
        what builds on that check runs: the accepted orders' mean placement (``combine_orders``) and the
        whole-map refinement (``refine_whole``). False (``roi_score``): each search step's ROI score ≥
        ``score_min``, the thesis's cross-correlation rule.
    nu : the check runs the thesis's rule, ω̃ ≥ ``nu_min`` on ≥ ``min_support`` cells (:func:`merger.team.verify.verify`).
    contrast : the check runs the contrast rule (:func:`merger.team.verify.verify_contrast`), and the guard
        beyond the window is settled on the whole maps (:func:`merger.team.orders.whole_map_guard`). With
        ``nu``: a pair passes when either rule passes it, the thesis's first.
    """

    name: str
    whole_maps: bool
    nu: bool = False
    contrast: bool = False


# one entry per rule, in the order the settings' words list them
VERIFICATIONS_BY_NAME: dict[str, VerificationRule] = {r.name: r for r in (
    VerificationRule("auto", whole_maps=True, nu=True, contrast=True),
    VerificationRule("whole_map", whole_maps=True, nu=True),
    VerificationRule("roi_score", whole_maps=False),
    VerificationRule("contrast", whole_maps=True, contrast=True),
)}
VERIFICATIONS = tuple(VERIFICATIONS_BY_NAME)  # the verification setting's allowed values


@dataclass(frozen=True)
class ResearchMode:
    """When a pair (tree) or the team's hypothesis (orders) is searched globally again (``MergeParams.research``).

    tracks : an accepted answer is re-verified by a local search about it at each map version, and searched
        globally only when due (:class:`merger.team.track.Tracker`); False: every version is searched
        globally (the thesis's behaviour)."""

    name: str
    tracks: bool


RESEARCH_MODES_BY_NAME: dict[str, ResearchMode] = {m.name: m for m in (
    ResearchMode("on_change", tracks=True),
    ResearchMode("every_version", tracks=False),
)}
RESEARCH_MODES = tuple(RESEARCH_MODES_BY_NAME)  # the research setting's allowed values


def _lookup(table: dict, name, setting: str):
    try:
        return table[name]
    except (KeyError, TypeError):
        raise ValueError(f"{setting} must be one of {', '.join(map(repr, table))}, got {name!r}") from None


def verification_rule(name: str) -> VerificationRule:
    """The verification rule named ``name`` (ValueError naming the choices when there is none)."""
    return _lookup(VERIFICATIONS_BY_NAME, name, "verification")


def research_mode(name: str) -> ResearchMode:
    """The research mode named ``name`` (ValueError naming the choices when there is none)."""
    return _lookup(RESEARCH_MODES_BY_NAME, name, "research")
