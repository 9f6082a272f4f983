"""The user's guide stays true: README size and test command, links that resolve, and the README's
scenario template and pytest guard run as printed."""

import re

import yaml

from tests.paths import REPO

ROOT = REPO
README = ROOT / "README.md"
TEST_COMMAND = 'python3 -m venv .venv && .venv/bin/pip install -e ".[test]" && .venv/bin/python -m pytest -q -n 2'


def block(text: str, after: str, lang: str) -> str:
    """The fenced ``lang`` block that follows the line ``after`` (or the first one after it)."""
    m = re.search(re.escape(after) + r".*?```" + lang + r"\n(.*?)```", text, re.S)
    assert m, f"no ```{lang} block after {after!r}"
    return m.group(1)


def test_readme_is_a_short_guide_with_the_ci_test_command():
    text = README.read_text()
    assert len(text.encode()) <= 15_000
    lines = text.splitlines()
    k = lines.index("<!-- test-command -->")
    assert lines[k + 2] == TEST_COMMAND  # .ci/run executes the line two below the marker
    assert not re.search(r"\bissue \d|\bsession\b", text, re.I), "project history belongs in docs/"


def test_every_relative_link_resolves():
    pages = [README, *sorted((ROOT / "docs").rglob("*.md"))]
    missing = []
    for page in pages:
        for target in re.findall(r"\]\(([^)\s]+)\)", page.read_text()):
            if re.match(r"[a-z]+:", target) or target.startswith("#"):
                continue
            if not (page.parent / target.split("#")[0]).exists():
                missing.append(f"{page.relative_to(ROOT)} → {target}")
    assert not missing, missing


def test_readme_scenario_template_is_valid():
    from circsim.config.scenario import scenario_from_dict

    sc = scenario_from_dict(yaml.safe_load(block(README.read_text(), "<!-- scenario-template -->", "yaml")),
                            source="my-room.yaml")
    assert sc.merger.window_m == 0.5 and len(sc.robots.names) == 4


def test_readme_pytest_guard_runs():
    code = block(README.read_text(), "**5. Guard a metric with pytest.**", "python")
    namespace: dict = {}
    exec(compile(code, "README.md", "exec"), namespace)  # noqa: S102 - the README's own example
    tests = [f for name, f in namespace.items() if name.startswith("test_")]
    assert len(tests) == 1
    tests[0]()
