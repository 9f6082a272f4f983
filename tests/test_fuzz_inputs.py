"""Property-based fuzzing of the user-facing readers (issue 12): generated bad input to the scenario loader,
``--set`` parsing and the ROS map reader. Whatever comes in, the only exception that may escape is the
documented one-line error — :class:`circsim.config.scenario.ScenarioError` or :class:`merger.io.mapread.MapFileError` —
never a traceback of something else. Examples per test are in ``EXAMPLES`` (docs/troubleshooting.md says how many).
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from circsim.config.scenario import (
    ScenarioError,
    bundled_scenarios,
    load_scenario,
    scenario_from_dict,
    scenario_to_dict,
)
from merger.grid import OccupancyGrid
from merger.io.mapio import load_map
from merger.io.mapread import MapFileError
from tests.paths import REPO

EXAMPLES = {"scenario_data": 400, "scenario_text": 200, "set": 400, "map_yaml": 300, "map_image": 200}


def fuzz(name: str):
    return settings(max_examples=EXAMPLES[name], deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])

BASE = load_scenario(bundled_scenarios()["scene1"])
BASE_DATA = scenario_to_dict(BASE)


def _paths(d, prefix=()):
    """Every key path of the resolved scene1 (mappings and list items)."""
    out = [prefix] if prefix else []
    if isinstance(d, dict):
        for k, v in d.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(d, list):
        for i, v in enumerate(d):
            out += _paths(v, (*prefix, i))
    return out


PATHS = _paths(BASE_DATA)
KEYS = sorted({str(p[-1]) for p in PATHS if isinstance(p[-1], str)})

numbers = st.one_of(st.integers(-10**12, 10**12), st.floats(allow_nan=True, allow_infinity=True),
                    st.sampled_from([0, -1, 1e-300, 1e300, 0.5, 2, 360, 1e6]))
scalars = st.one_of(numbers, st.booleans(), st.none(), st.text(max_size=12),
                    st.sampled_from(["fast", "reference", "chair", "box", "online", "offline", "Lyon", ""]))
values = st.recursive(scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=5),
    st.dictionaries(st.one_of(st.sampled_from(KEYS), st.text(max_size=8)), inner, max_size=4)), max_leaves=12)


def one_line(e: Exception) -> None:
    msg = str(e)
    assert msg and "\n" not in msg and "Traceback" not in msg, msg


def _set_path(data, path, value):
    node = data
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value


@fuzz("scenario_data")
@given(edits=st.lists(st.tuples(st.sampled_from(PATHS), values), min_size=1, max_size=3),
       extra=st.one_of(st.none(), st.tuples(st.text(max_size=8), values)))
@pytest.mark.slow
def test_scenario_loader_refuses_bad_values_in_one_line(edits, extra):
    data = copy.deepcopy(BASE_DATA)
    for path, value in edits:
        try:
            _set_path(data, path, value)
        except (KeyError, IndexError, TypeError):  # an earlier edit replaced a parent
            pass
    if extra is not None:
        data[extra[0]] = extra[1]
    try:
        sc = scenario_from_dict(data, source="fuzz.yaml")
    except ScenarioError as e:
        one_line(e)
        assert str(e).startswith("fuzz.yaml")
        return
    assert math.isfinite(sc.duration_s) and sc.duration_s > 0  # accepted: a usable scenario
    assert scenario_from_dict(scenario_to_dict(sc)) == sc


@fuzz("scenario_text")
@given(text=st.one_of(
    st.text(max_size=200),
    st.builds(lambda v: yaml.safe_dump(v, allow_unicode=True), values),
    st.sampled_from(["", "#", "---\n...", "a: [", "!!python/object:os.system {}", "x: &a [*a]", "[1, 2]",
                     "when: 2001-13-01", "seed: 1e400", "{" * 500, "- " * 300])))
def test_scenario_files_of_any_text(tmp_path_factory, text):
    p = tmp_path_factory.mktemp("fz") / "fuzz.yaml"
    p.write_bytes(text.encode("utf-8", "surrogatepass"))
    try:
        load_scenario(p)
    except ScenarioError as e:
        one_line(e)
        assert str(e).startswith("fuzz.yaml")


set_keys = st.one_of(st.sampled_from([".".join(map(str, p)) for p in PATHS if all(isinstance(k, str) for k in p)]),
                     st.text(max_size=20))
set_values = st.one_of(st.text(max_size=30), st.builds(lambda v: yaml.safe_dump(v, default_flow_style=True)
                                                       .strip(), values),
                       st.sampled_from(["nan", ".nan", "-.inf", "1e1", "1e999", "[", "{a: 1", "~", "1_000", "0x1f",
                                        "2001-13-01", "!!binary x", "&a [*a]"]))


@fuzz("set")
@given(assignments=st.lists(st.one_of(st.builds(lambda k, v: f"{k}={v}", set_keys, set_values),
                                      st.text(max_size=30)), min_size=1, max_size=3))
def test_set_assignments_refused_in_one_line(assignments):
    try:
        BASE.with_overrides(assignments)
    except ScenarioError as e:
        one_line(e)
        assert str(e).startswith("scene1.yaml")


MAP_META = {"image": "m.pgm", "resolution": 0.05, "origin": [-1.0, 2.0, 0.0], "negate": 0,
            "occupied_thresh": 0.65, "free_thresh": 0.196, "mode": "trinary"}
meta_values = st.one_of(values, st.lists(numbers, min_size=2, max_size=4))


def _write_pgm(path, img):
    h, w = img.shape
    path.write_bytes(f"P5\n# CREATOR: map_saver.cpp 0.050 m/pix\n{w} {h}\n255\n".encode() + img.tobytes())


@fuzz("map_yaml")
@given(edits=st.dictionaries(st.sampled_from([*MAP_META, "extra"]), st.one_of(meta_values, st.just("DELETE")),
                             max_size=4),
       raw=st.one_of(st.none(), st.text(max_size=120)))
def test_map_yaml_refused_in_one_line(tmp_path_factory, edits, raw):
    d = tmp_path_factory.mktemp("map")
    _write_pgm(d / "m.pgm", np.full((4, 6), 254, np.uint8))
    meta = dict(MAP_META)
    for k, v in edits.items():
        if v == "DELETE":
            meta.pop(k, None)
        else:
            meta[k] = v
    (d / "m.yaml").write_bytes((raw if raw is not None else yaml.safe_dump(meta, allow_unicode=True))
                               .encode("utf-8", "surrogatepass"))
    try:
        g = load_map(d / "m.yaml")
    except MapFileError as e:
        one_line(e)
        return
    assert isinstance(g, OccupancyGrid) and g.resolution > 0 and all(map(math.isfinite, g.origin))


@fuzz("map_image")
@given(data=st.one_of(
    st.binary(max_size=300),
    st.builds(lambda w, h, body: f"P5\n{w} {h}\n255\n".encode() + body,
              st.integers(-3, 70000), st.integers(-3, 70000), st.binary(max_size=200)),
    st.builds(lambda res, body: f"P5\n# CREATOR: map_saver.cpp {res} m/pix\n3 2\n255\n".encode() + body,
              st.sampled_from(["0.050", "0.1", "nan", "1e999", "-0.05", "0", "x"]), st.binary(min_size=6,
                                                                                               max_size=6))),
       suffix=st.sampled_from([".pgm", ".png"]))
def test_map_image_bytes_refused_in_one_line(tmp_path_factory, data, suffix):
    d = tmp_path_factory.mktemp("img")
    (d / f"m{suffix}").write_bytes(data)
    (d / "m.yaml").write_text(f"image: m{suffix}\nresolution: 0.05\norigin: [0, 0, 0]\n")
    try:
        g = load_map(d / "m.yaml")
    except MapFileError as e:
        one_line(e)
        return
    assert isinstance(g, OccupancyGrid) and g.states.size > 0


def test_example_counts_are_what_the_docs_say():

    page = (REPO / "docs" / "troubleshooting.md").read_text()
    total = sum(EXAMPLES.values())
    assert f"{total} generated inputs" in page


@pytest.mark.parametrize("text", ["seed: .nan", "duration_s: -.inf", "robots: {names: [A, A]}",
                                  "world: {objects: [{type: []}]}", "merger: {method: [fast]}",
                                  "robots: {heading: {a: 1}}", "merger: {measure: [ncc]}"])
def test_a_few_known_bad_files(tmp_path, text):
    (tmp_path / "s.yaml").write_text(text)
    with pytest.raises(ScenarioError):
        load_scenario(tmp_path / "s.yaml")
