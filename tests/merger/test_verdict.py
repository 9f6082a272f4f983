"""merger.verdict: the verdict's words name the rule that decided, with the figures of that rule."""

from types import SimpleNamespace as NS

from merger.verdict import ALGORITHM_RULE, RULE_NAMES, evidence_text, refusal, rule_of, verdict_words

NAN = float("nan")


def contrast(best=0.412, rival=0.133, rival_at=(90.0, 0.0), value=3.1, support=812):
    return NS(best=best, rival=rival, rival_at=rival_at, contrast=value, support=support)


def test_evidence_names_the_figures_of_the_rule_that_decided():
    assert evidence_text(NS(nu=0.4567, support=1234, contrast=None), "a|b") == "a|b ν 0.457 (1234 cells)"
    assert evidence_text(NS(nu=0.46, support=0, contrast=contrast()), "r1|r2") == (
        "r1|r2 contrast 3.10 (fit 0.412 vs rival 0.133 at +90°, 812 cells; ν 0.46)")
    assert evidence_text(NS(nu=0.3, support=0, contrast=contrast(rival=0.0, value=NAN))) == (
        "contrast – (fit 0.412 vs no rival, 812 cells; ν 0.30)")
    assert evidence_text(NS(nu=0.3, support=0, contrast=contrast(rival=NAN))).startswith(
        "contrast 3.10 (fit 0.412 vs rival not computed (the fit's angle already refuses)")
    assert evidence_text(NS(nu=0.1, support=0, contrast=contrast(best=NAN, support=12))) == (
        "12 cells under the contrast rule; ν 0.10")


def test_rule_of_the_checks():
    assert rule_of([NS(contrast=None), NS(contrast=contrast())]) == "contrast"
    assert rule_of([NS(contrast=None)]) == "whole-map ν"
    assert rule_of([]) == ALGORITHM_RULE


def test_a_refusal_names_its_rule_without_repeating_its_prefix():
    res = NS(chosen=None, rule="guard", reason="beyond the window: a better placement 0.8 m away")
    assert refusal(res) == "the guard beyond the window: a better placement 0.8 m away"
    assert verdict_words(res) == ("the guard beyond the window", "a better placement 0.8 m away")
    amb = NS(chosen=None, rule="ambiguity", reason="ambiguous: runner-up at 180° within 0.02")
    assert verdict_words(amb) == (RULE_NAMES["ambiguity"], "runner-up at 180° within 0.02")


def test_an_accepted_cycle_names_the_rule_and_each_pairs_figures():
    checks = {"a|b": NS(nu=0.5, support=100, contrast=None), "a|c": NS(nu=0.61, support=90, contrast=None)}
    res = NS(chosen=NS(checks=checks), rule=None, reason="")
    assert verdict_words(res) == ("whole-map ν", "a|b ν 0.500 (100 cells); a|c ν 0.610 (90 cells)")
