"""The user's guide stays true: README size and test command, links that resolve, and the README's
scenario template and pytest guard run as printed."""

import re

import pytest
import yaml

from tests.paths import REPO

ROOT = REPO
README = ROOT / "README.md"
# the site is built strictly before the tests; no -q: mkdocs' --quiet drops the warnings strict mode counts
TEST_COMMAND = ('python3 -m venv .venv && .venv/bin/pip install -e ".[test,docs]" && .venv/bin/mkdocs build --strict '
                '&& .venv/bin/python -m pytest -q -n 2')


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


def python_examples():
    """Every ```python block of the README and docs/ as (page, index, code)."""
    out = []
    for page in [README, *sorted((ROOT / "docs").rglob("*.md"))]:
        for k, code in enumerate(re.findall(r"```python\n(.*?)```", page.read_text(), re.S)):
            out.append(pytest.param(page, code, id=f"{page.relative_to(ROOT)}#{k + 1}"))
    return out


@pytest.mark.parametrize(("page", "code"), python_examples())
def test_every_python_example_in_the_docs_runs(page, code, tmp_path, monkeypatch, capsys):
    """Each example runs as printed: from the shared real maps' folder for the pages on real maps (they name
    its files), from an empty folder otherwise. What the real-map example prints is checked against the
    Halmstad truth (gt_pairs.csv: E5_01's frame in E5_02's, good to its RMS)."""
    from tests.realdata import DATA, MISSING, have_data

    if page.name == "real-maps.md":
        if not have_data():
            pytest.skip(MISSING)
        monkeypatch.chdir(DATA)
    else:
        monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__doc_example__"}
    exec(compile(code, str(page), "exec"), namespace)  # noqa: S102 - the docs' own example
    out = capsys.readouterr().out
    if page.name == "real-maps.md":
        import csv
        import math

        from merger import Pose

        res = namespace["res"]
        assert res.accepted and out.startswith(f"accepted by {res.rule} - ")
        row = next(r for r in csv.DictReader(open(DATA / "halmstad" / "gt_pairs.csv"))
                   if (r["map_a"], r["map_b"]) == ("E5_01", "E5_02"))
        truth = Pose(float(row["tx_m"]), float(row["ty_m"]), float(row["theta_deg"]) % 360)
        rms_m = float(row["rms_px"]) * float(row["tx_m"]) / float(row["tx_px"])
        got = res.poses["E5_01"]
        assert abs((got.yaw_deg - truth.yaw_deg + 180) % 360 - 180) <= 3.0
        center = (48.6, 41.4)  # where the common center lands: the truth's tolerance (tests/realdata.py)
        assert math.dist(got.apply(center), truth.apply(center)) <= 0.5 + rms_m
        assert f"E5_01 in E5_02's frame: x {got.x:+.3f} m, y {got.y:+.3f} m, yaw {got.yaw_deg:.2f} deg" in out
