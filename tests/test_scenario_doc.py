"""docs/scenario-reference.md is generated from the scenario loader's checks and must be current."""

from pathlib import Path

from circsim.cli import main
from circsim.scenario import _TOP
from circsim.scenario_doc import scenario_reference

DOC = Path(__file__).resolve().parents[1] / "docs" / "scenario-reference.md"


def test_reference_in_docs_is_current():
    assert DOC.read_text() == scenario_reference(), (
        "docs/scenario-reference.md is stale: run `circsim scenarios --reference > docs/scenario-reference.md`")


def test_reference_lists_every_section_and_the_cli_prints_it(capsys):
    text = scenario_reference()
    for key in _TOP:
        assert f"`{key}" in text, key
    for row in ("| `merger.nu_min` | `0.5` | a number in [0, 1] |", "| `world.pillars[].radius` | `0.2` |",
                "| `world.objects[].center` | (required) |", "`latency` → `network.latency_s`"):
        assert row in text, row
    assert main(["scenarios", "--reference"]) == 0
    assert capsys.readouterr().out == text
