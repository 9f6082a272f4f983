"""merger.cli.checks: the command line's own checks refuse in one line naming the option; the library's
refusals reach the user named by the option they typed (options_named); --roi in cells is the library's
rule word for word."""

from argparse import Namespace
from pathlib import Path

import pytest

from merger.cli.checks import (
    center_keys,
    centers_of,
    check_demo_options,
    check_output_folder,
    check_roi,
    check_stem,
    options_named,
    pair_names,
    parse_xy,
)
from merger.cli.parser import UsageError
from merger.inputs import MergeInputError
from merger.settings import SettingError
from merger.settings import check_roi as roi_rule
from merger.team.params import MergeParams


def refused(fn, *args) -> str:
    with pytest.raises(UsageError) as e:
        fn(*args)
    assert "\n" not in str(e.value)
    return str(e.value)


def test_xy_text():
    assert parse_xy("-1.5,2e-1", "--center") == (-1.5, 0.2)
    assert refused(parse_xy, "1;2", "--center") == "--center: expected X,Y in metres (e.g. 1.5,-0.25), got '1;2'"
    assert refused(parse_xy, "1,2,3", "--center").startswith("--center: expected X,Y")
    assert refused(parse_xy, "nan,0", "--real-center") == "--real-center: expected finite numbers, got 'nan,0'"


def test_centers_once_or_once_per_map_and_how_they_are_named():
    assert centers_of(["1,2"], 3) == [(1.0, 2.0)] * 3
    assert centers_of(["1,2", "3,4"], 2) == [(1.0, 2.0), (3.0, 4.0)]
    assert refused(centers_of, ["1,2", "3,4"], 3, "topic") == "--center: expected once or once per topic (3), got 2"
    assert center_keys([(1, 2), (1, 2)]) == {"centers[0]": "--center", "centers[1]": "--center"}
    assert center_keys([(1, 2), (3, 4)]) == {"centers[0]": "--center (map 1)", "centers[1]": "--center (map 2)"}


def test_library_refusals_are_named_by_the_option():
    with pytest.raises(UsageError) as e, options_named({"centers[1]": "--center-moving"}):
        raise MergeInputError("centers[1]", ": expected finite numbers, got (nan, 0)")
    assert str(e.value) == "--center-moving: expected finite numbers, got (nan, 0)"
    with pytest.raises(UsageError) as e, options_named({}):
        raise MergeInputError("window_m", " = 3 m is more than a quarter of the ROI side")
    assert str(e.value) == "--window = 3 m is more than a quarter of the ROI side"
    with pytest.raises(KeyError), options_named({}):  # anything else passes through
        raise KeyError("x")


@pytest.mark.parametrize("roi, res", [(0.3, 0.05), (40.0, 0.005), (float("nan"), 0.05), (8.0, 0.05)])
def test_roi_in_cells_is_the_library_rule_named_roi(roi, res):
    try:
        roi_rule(roi, res, "--roi", limits=True, cells_of="m.yaml")
    except SettingError as e:
        assert refused(check_roi, roi, res, "m.yaml") == str(e)
    else:
        check_roi(roi, res, "m.yaml")


def test_output_stems_and_folders(tmp_path):
    (tmp_path / "file").write_text("")
    assert check_stem(tmp_path / "merged", "-o") == tmp_path / "merged"
    # as typed: "out/" names a folder (a Path would drop the slash, and the map would be written as out.yaml)
    for bad in (Path("."), Path(".."), tmp_path, "out/", f"{tmp_path}/new/"):
        assert refused(check_stem, bad, "-o").startswith("-o: expected an output file stem such as out/merged")
    assert refused(check_stem, tmp_path, "-o").endswith("(a folder)")
    assert check_output_folder(tmp_path / "new", "-o") == tmp_path / "new"
    assert refused(check_output_folder, tmp_path / "file", "-o") == (
        f"-o {tmp_path / 'file'}: expected an output folder, got an existing file")


def demo(**kw):
    args = {"arc": 30.0, "radius": None, "center_error": 0.0, "seed": 7, "real": None, "real_center": None, **kw}
    return Namespace(**args)


@pytest.mark.parametrize("kw, words", [
    ({"arc": 181.0}, "--arc: expected a number of degrees in [0, 180], got 181"),
    ({"arc": float("nan")}, "--arc: expected a number of degrees in [0, 180], got nan"),
    ({"radius": 2.5}, "--radius: expected a number of metres in (0, 2.4] (the generated room is 8 x 6 m about "
                      "the center), got 2.5"),
    ({"radius": 5.5, "real": Path("m.yaml")}, "--radius: expected a number of metres in (0, 5] (the robots' "
                                              "views are 12 m maps cut around their arcs), got 5.5"),
    ({"center_error": 4.5}, "--center-error: expected a number of metres in [0, 4] (half the --roi"),
    ({"seed": -1}, "--seed: expected an integer >= 0, got -1"),
    ({"real_center": "1,2"}, "--real-center: only with --real MAP.yaml"),
])
def test_the_demos_options(kw, words):
    assert refused(check_demo_options, demo(**kw), MergeParams()).startswith(words)


def test_the_demos_defaults_and_limits_pass():
    check_demo_options(demo(), MergeParams())
    check_demo_options(demo(arc=180.0, radius=2.4, center_error=4.0, seed=0), MergeParams())
    check_demo_options(demo(radius=5.0, real=Path("m.yaml"), real_center="1,2"), MergeParams())


def test_pair_names(tmp_path):
    a, b = tmp_path / "r1" / "map.yaml", tmp_path / "r2" / "map.yaml"
    assert pair_names(tmp_path / "Lyon.yaml", tmp_path / "Nevers.yaml") == ("Lyon", "Nevers")
    assert pair_names(a, b) == ("r1/map", "r2/map")
    assert pair_names(a, a) == ("ref", "moving")  # one file twice (align MAP MAP)
