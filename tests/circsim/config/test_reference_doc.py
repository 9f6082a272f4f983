"""docs/scenario-reference.md is generated from the scenario loader's checks and must be current."""


from circsim.cli import main
from circsim.config.reference_doc import scenario_reference
from circsim.config.scenario import TOP_KEYS
from tests.paths import REPO

DOC = REPO / "docs" / "scenario-reference.md"


def test_reference_in_docs_is_current():
    assert DOC.read_text() == scenario_reference(), (
        "docs/scenario-reference.md is stale: run `circsim scenarios --reference > docs/scenario-reference.md`")


def test_reference_lists_every_section_and_the_cli_prints_it(capsys):
    text = scenario_reference()
    for key in TOP_KEYS:
        assert f"`{key}" in text, key
    for row in ("| `merger.nu_min` | `0.5` | a number in [0, 1] — ν is ω̃", "| `world.pillars[].radius` | `0.2` |",
                "| `world.objects[].center` | (required) |", "`latency` → `network.latency_s`"):
        assert row in text, row
    assert main(["scenarios", "--reference"]) == 0
    assert capsys.readouterr().out == text


def test_every_default_in_the_reference_is_the_loaders():
    """The table's defaults are what `circsim scenarios --show` resolves for an empty scenario; a default
    that follows another key says so and the loader follows it."""
    import json
    import re

    from circsim.config.reference_doc import DERIVED_DEFAULTS
    from circsim.config.scenario import scenario_from_dict, scenario_to_dict

    resolved = scenario_to_dict(scenario_from_dict({}, default_name="x"))
    resolved.update(seed=scenario_from_dict({}, default_name="x").seed)
    generated = scenario_to_dict(scenario_from_dict({"world": {"generate": {"kind": "floorplan"}}}, default_name="x"))
    checked = 0
    for key, default in re.findall(r"^\| `([^`]+)` \| `([^`]*)` \|", scenario_reference(), re.M):
        if "[]" in key or key in DERIVED_DEFAULTS:
            continue
        node = generated if key.startswith("world.generate.") else resolved
        for part in key.split("."):
            node = node[part]
        assert json.loads(default) == node, (key, default, node)
        checked += 1
    assert checked > 50
    for key, words in DERIVED_DEFAULTS.items():
        assert f"| `{key}` | {words} |" in scenario_reference()
    sc = scenario_from_dict({"world": {"center": [0.5, -0.25], "room": {"size_m": [8, 6]}}}, default_name="x")
    assert tuple(sc.world.room.center) == (0.5, -0.25)  # the room follows world.center


def test_show_prints_start_angles_in_0_360(capsys, tmp_path):
    """Five robots spread from 90°: 90, 162, 234, 306 and 18 (not 378), as DESIGN.md reports angles."""
    (tmp_path / "five.yaml").write_text("robots: {names: [A, B, C, D, E]}\nduration_s: 1\n")
    assert main(["scenarios", "--show", str(tmp_path / "five.yaml")]) == 0
    out = capsys.readouterr().out
    assert "start_angles_deg: [90.0, 162.0, 234.0, 306.0, 18.0]" in out, out
