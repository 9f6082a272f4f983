"""merger.team.defaults (issue 45): the team's settings at the bottom of merger/team/ — each named setting's
table of objects (verification rules, research modes) and the defaults the lower modules read. The settings'
allowed values are the tables' keys, and no module chooses by comparing a setting's name with a string."""

from __future__ import annotations

import ast

import pytest

from merger.cli.parser import CLI_VERIFICATIONS
from merger.team import defaults, evidence, params, track
from merger.team.defaults import (
    RESEARCH_MODES,
    RESEARCH_MODES_BY_NAME,
    VERIFICATIONS,
    VERIFICATIONS_BY_NAME,
    research_mode,
    verification_rule,
)
from merger.team.params import RULES, MergeParams
from tests.paths import REPO


def test_the_allowed_values_are_the_tables_keys():
    assert VERIFICATIONS == tuple(VERIFICATIONS_BY_NAME) == ("auto", "whole_map", "roi_score", "contrast")
    assert RESEARCH_MODES == tuple(RESEARCH_MODES_BY_NAME) == ("on_change", "every_version")
    assert RULES["verification"].expected == "one of " + ", ".join(map(repr, VERIFICATIONS))
    assert RULES["research"].expected == "one of " + ", ".join(map(repr, RESEARCH_MODES))
    assert params.VERIFICATIONS is VERIFICATIONS  # its old path
    # the command line offers the rules that check pairs on the whole maps (roi_score has no --score-min)
    assert CLI_VERIFICATIONS == ("auto", "whole_map", "contrast")


def test_each_verification_rule_says_what_differs():
    flags = {n: (r.whole_maps, r.nu, r.contrast) for n, r in VERIFICATIONS_BY_NAME.items()}
    assert flags == {"auto": (True, True, True), "whole_map": (True, True, False),
                     "roi_score": (False, False, False), "contrast": (True, False, True)}
    for name, rule in VERIFICATIONS_BY_NAME.items():
        assert rule.name == name and verification_rule(name) is rule
        assert MergeParams(verification=name).verification_rule is rule
    with pytest.raises(ValueError, match="verification must be one of 'auto', 'whole_map', 'roi_score', "
                                         "'contrast', got 'thesis'"):
        verification_rule("thesis")


def test_each_research_mode_says_whether_answers_are_tracked():
    assert {n: m.tracks for n, m in RESEARCH_MODES_BY_NAME.items()} == {"on_change": True, "every_version": False}
    for name, mode in RESEARCH_MODES_BY_NAME.items():
        assert mode.name == name and research_mode(name) is mode
        assert MergeParams(research=name).research_mode is mode
    with pytest.raises(ValueError, match="research must be one of 'on_change', 'every_version', got 'never'"):
        research_mode("never")


def test_the_defaults_live_here_and_keep_their_old_names():
    values = {"TOLERANCE_M": 0.2, "CONTRAST_MIN": 1.5, "RESEARCH_DEFAULT": "on_change", "RESEARCH_PERIOD_S": 10.0,
              "RESEARCH_CHANGE": 0.1, "RESEARCH_DROP": 0.1}
    for name, value in values.items():
        assert getattr(defaults, name) == value, name
    for name in ("TOLERANCE_M", "CONTRAST_MIN"):
        assert getattr(evidence, name) is getattr(defaults, name)
    for name in ("RESEARCH_MODES", "RESEARCH_DEFAULT", "RESEARCH_PERIOD_S", "RESEARCH_CHANGE", "RESEARCH_DROP"):
        assert getattr(track, name) is getattr(defaults, name)
    d = MergeParams()
    assert (d.tolerance_m, d.contrast_min, d.research, d.research_period_s, d.research_change, d.research_drop) == \
        (0.2, 1.5, "on_change", 10.0, 0.1, 0.1)


PENDING: dict[str, int] = {}  # modules that may still compare a setting's name with a string, and how often: none
SETTINGS = ("verification", "strategy", "algorithm", "research")


def _names_a_setting(node: ast.expr) -> bool:
    """``params.verification``, ``strategy``, ``resolve_strategy(...)``: an expression that names a setting."""
    if isinstance(node, ast.Call):
        node = node.func
    name = node.attr if isinstance(node, ast.Attribute) else node.id if isinstance(node, ast.Name) else ""
    return any(s in name for s in SETTINGS)


def _is_text(node: ast.expr) -> bool:
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return bool(node.elts) and all(_is_text(e) for e in node.elts)
    return isinstance(node, ast.Constant) and isinstance(node.value, str)


def name_comparisons(source: str) -> list[int]:
    """The lines of ``source`` that compare a setting's name with a string (``==``, ``!=``, ``in``)."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any(_names_a_setting(s) for s in sides) and any(_is_text(s) for s in sides):
                out.append(node.lineno)
    return out


def test_the_comparison_finder_finds_them():
    src = ('if params.verification != "roi_score": pass\nif strategy == "auto": pass\n'
           'if self.algorithm not in ("a", "b"): pass\nif resolve_strategy(s, n) == "tree": pass\n'
           'if s["algorithm"] == a: pass\nif algorithm not in ALGORITHMS: pass\n')
    assert name_comparisons(src) == [1, 2, 3, 4]


def test_no_module_chooses_by_comparing_a_setting_name():
    found = {}
    for pkg in ("merger", "circsim"):
        for p in sorted((REPO / pkg).rglob("*.py")):
            lines = name_comparisons(p.read_text())
            rel = p.relative_to(REPO).as_posix()
            if len(lines) > PENDING.get(rel, 0):
                found[rel] = lines
    assert not found, f"choose by the setting's table (merger.team.defaults, online.STRATEGIES_BY_NAME, " \
                      f"merger.algorithms.ALGORITHMS_BY_NAME), not by its name: {found}"


def test_the_two_agreement_angles_are_named_apart():
    """Issue 45: evidence's 4° (the whole maps' best fit near the placement) and track's 10° (two answers are
    one hypothesis) were both AGREE_DEG."""
    assert evidence.FIT_AGREE_DEG == 4.0 and track.SAME_HYPOTHESIS_DEG == 10.0
    assert not any(hasattr(m, "AGREE_DEG") for m in (defaults, evidence, params, track))
