"""Every lemma the code cites is stated in docs/design/search.md: each "Lemma <id>" written in the
sources (merger/, circsim/ and the tests) has a "**Lemma <id>" heading in the design note, and no
heading is written twice. A placeholder such as "Lemma N" cites nothing."""

from __future__ import annotations

import re
from collections import defaultdict

from tests.paths import REPO, TESTS

DOC = REPO / "docs" / "design" / "search.md"
SOURCES = (REPO / "merger", REPO / "circsim", TESTS)
ID = r"\d+[a-z]?"
# "Lemma 3b", and lists: "Lemmas 5 and 5b", "Lemmas 3, 3b or 6"
CITATION = re.compile(rf"\bLemmas? ({ID}(?:(?:, | and | or |, and ){ID})*)\b")
HEADING = re.compile(rf"^\*\*Lemma ({ID})\b", re.M)


def cited() -> dict[str, list[str]]:
    """Lemma id → the places ("path:line") that cite it."""
    out: dict[str, list[str]] = defaultdict(list)
    for root in SOURCES:
        for path in sorted(root.rglob("*.py")):
            if path.is_relative_to(TESTS / "docs"):
                continue  # this test names lemmas only in its patterns
            for no, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
                for m in CITATION.finditer(line):
                    for lemma in re.findall(ID, m.group(1)):
                        out[lemma].append(f"{path.relative_to(REPO)}:{no}")
    return out


def stated() -> list[str]:
    return HEADING.findall(DOC.read_text(encoding="utf-8"))


def test_the_scan_finds_the_codes_citations():
    ids = cited()
    assert {"1", "3", "3b", "5"} <= ids.keys(), sorted(ids)  # the pattern still reads the citations


def test_every_cited_lemma_is_stated_in_the_design_note():
    have = set(stated())
    missing = {lemma: places for lemma, places in sorted(cited().items()) if lemma not in have}
    assert not missing, f"cited but not stated in {DOC.relative_to(REPO)}: {missing}"


def test_each_lemma_is_stated_once():
    heads = stated()
    twice = sorted({h for h in heads if heads.count(h) > 1})
    assert not twice, f"stated more than once: {twice}"
