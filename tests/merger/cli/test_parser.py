"""merger.cli.parser: the grammar of ``merger align | merge | demo`` — every merge option defaults to
MergeParams's setting and is parsed into it, a negative center passes argparse, a parse error is one
line (UsageError), not argparse's usage block and exit."""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from merger.cli.parser import (
    CLI_VERIFICATIONS,
    OPTIONS,
    UsageError,
    build_parser,
    join_negative_xy,
    package_version,
)
from merger.team.defaults import VERIFICATIONS_BY_NAME
from merger.team.params import MergeParams

ALIGN = ["align", "a.yaml", "b.yaml", "--center", "0,0"]
MERGE = ["merge", "a.yaml", "b.yaml", "--center", "0,0", "-o", "out"]


@pytest.mark.parametrize("argv, want", [
    (["--center", "-1.2,0.5"], ["--center=-1.2,0.5"]),
    (["--center-moving", "-3,-4", "x"], ["--center-moving=-3,-4", "x"]),
    (["--real-center", "-.5,1"], ["--real-center=-.5,1"]),
    (["--center", "-inf,0"], ["--center=-inf,0"]),  # joined: the value's own check refuses it, by name
    (["--center", "1.2,-0.5"], ["--center", "1.2,-0.5"]),  # not negative first: argparse takes it as is
    (["--center", "-1.2"], ["--center", "-1.2"]),  # no pair: left to argparse
    (["--center", "--json"], ["--center", "--json"]),  # an option, not a value
    (["--roi", "-3,4"], ["--roi", "-3,4"]),  # only the X,Y options
    (["--", "--center", "-1,2"], ["--", "--center", "-1,2"]),  # after --: left alone
    (["--center"], ["--center"]),
])
def test_join_negative_xy(argv, want):
    assert join_negative_xy(argv) == want


@settings(max_examples=50, deadline=None)
@given(x=st.floats(-100, -1e-3), y=st.floats(-100, 100))
def test_a_negative_center_parses_to_its_text(x, y):
    args = build_parser().parse_args(join_negative_xy(["align", "a.yaml", "b.yaml", "--center", f"{x!r},{y!r}"]))
    assert args.center == f"{x!r},{y!r}"


@pytest.mark.parametrize("argv", [ALIGN, MERGE, ["demo"]])
def test_every_merge_option_defaults_to_merge_params(argv):
    args = build_parser().parse_args(argv)
    d = MergeParams()
    present = {name for name, (_, dest) in OPTIONS.items() if hasattr(args, dest)}
    assert present == set(OPTIONS) - ({"combine_orders"} if argv[0] == "align" else set())  # align: one pair
    for name in present:
        assert getattr(args, OPTIONS[name][1]) == getattr(d, name), name


def test_every_option_names_a_merge_setting_and_sets_it():
    fields = {f.name for f in dataclasses.fields(MergeParams)}
    assert set(OPTIONS) <= fields
    values = {"--roi": "12.5", "--measure": "ncc", "--method": "reference", "--window": "0.25", "--nu-min": "0.7",
              "--min-support": "123", "--verification": "contrast", "--tolerance": "0.2", "--contrast-min": "1.7",
              "--roi-min-support": "9"}
    flags = ["--no-refine", "--no-refine-whole", "--no-combine-orders"]
    argv = MERGE + [x for k, v in values.items() for x in (k, v)] + flags
    args = build_parser().parse_args(argv)
    got = {name: getattr(args, dest) for name, (_, dest) in OPTIONS.items()}
    assert got == {"roi_m": 12.5, "measure": "ncc", "method": "reference", "window_m": 0.25, "refine": False,
                   "refine_whole": False, "combine_orders": False, "nu_min": 0.7, "min_support": 123,
                   "verification": "contrast", "tolerance_m": 0.2, "contrast_min": 1.7, "roi_min_support": 9}
    assert set(OPTIONS[n][0] for n in OPTIONS) == set(values) | set(flags)


def test_the_verifications_offered_are_the_whole_map_rules():
    assert CLI_VERIFICATIONS and all(VERIFICATIONS_BY_NAME[v].whole_maps for v in CLI_VERIFICATIONS)
    assert set(CLI_VERIFICATIONS) == {v for v, r in VERIFICATIONS_BY_NAME.items() if r.whole_maps}
    with pytest.raises(UsageError, match="--verification: invalid choice"):
        build_parser().parse_args(MERGE + ["--verification", "nonsense"])


@pytest.mark.parametrize("argv, match", [
    ([], "the following arguments are required: cmd"),
    (["align", "a.yaml", "b.yaml"], "the following arguments are required: --center"),
    (["merge", "a.yaml", "--center", "0,0"], "the following arguments are required: -o/--output"),
    (MERGE + ["--roi", "big"], "argument --roi: invalid float value: 'big'"),
    (MERGE + ["--measure", "ssd"], "argument --measure: invalid choice: 'ssd'"),
    (MERGE + ["--algorithm", "orb"], "argument --algorithm: invalid choice: 'orb'"),
    (ALIGN + ["--no-combine-orders"], "unrecognized arguments: --no-combine-orders"),
    (["frobnicate"], "invalid choice: 'frobnicate'"),
])
def test_a_parse_error_is_one_usage_error_line(argv, match, capsys):
    with pytest.raises(UsageError) as e:
        build_parser().parse_args(argv)
    assert match in str(e.value) and "\n" not in str(e.value)
    assert capsys.readouterr().err == ""  # argparse's usage block is not printed


def test_merge_collects_centers_and_demo_has_its_own_defaults():
    args = build_parser().parse_args(["merge", "a.yaml", "b.yaml", "c.yaml", "--center", "0,0", "--center", "1,1",
                                      "--center", "2,2", "-o", "x/out", "--force"])
    assert [str(p) for p in args.maps] == ["a.yaml", "b.yaml", "c.yaml"]
    assert args.center == ["0,0", "1,1", "2,2"] and args.output == "x/out" and args.force
    assert args.algorithm == "thesis"
    demo = build_parser().parse_args(["demo"])
    assert (demo.seed, demo.arc, demo.center_error, demo.real, demo.radius) == (7, 30.0, 0.0, None, None)


def test_version(capsys):
    with pytest.raises(SystemExit) as e:
        build_parser().parse_args(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"merger {package_version()}"
    assert package_version()
