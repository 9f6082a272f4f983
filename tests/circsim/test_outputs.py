"""circsim.outputs: ``circsim run``'s outputs refused before the first tick, in one line naming the option —
a folder or a non-folder in the way, an output that is the scenario file or another output, an output
inside the bag's folder, an existing bag — and no check creates anything; the folders are made only by
:func:`make_folders`."""

from __future__ import annotations

from pathlib import Path

import pytest

from circsim.commands import UsageError
from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.outputs import check_bag_output, check_maps_folder, check_run_outputs, make_folders, writable
from merger.io.mapread import MapFileError


@pytest.fixture(scope="module")
def sc():
    return load_scenario(bundled_scenarios()["scene1"])


def _tree(root: Path) -> set:
    return {p.relative_to(root) for p in root.rglob("*")}


def test_writable_refuses_a_folder_or_a_file_in_the_way_and_creates_nothing(tmp_path):
    (tmp_path / "dir").mkdir()
    with pytest.raises(UsageError, match=r"dir: cannot write the recording here \(a folder has that name\)"):
        writable(tmp_path / "dir", "recording")
    (tmp_path / "file").write_text("x")
    with pytest.raises(UsageError, match=r"cannot write the recording here \(.*file is not a folder\)"):
        writable(tmp_path / "file" / "sub" / "run.rrd", "recording")
    before = _tree(tmp_path)
    writable(tmp_path / "a" / "b" / "run.rrd", "recording")  # missing folders: fine, and not made
    assert _tree(tmp_path) == before


def test_a_run_may_not_write_one_file_twice_or_over_its_scenario(sc, tmp_path):
    x = tmp_path / "x"
    with pytest.raises(MapFileError, match=r"--json .*x: is also written by --rrd"):
        check_run_outputs(sc, "scene1", x, x, None)
    scen = tmp_path / "my.yaml"
    scen.write_text("name: s\n")
    with pytest.raises(MapFileError, match=r"--json .*my.yaml: is also an input \(scenario"):
        check_run_outputs(sc, str(scen), None, scen, None)
    maps = tmp_path / "maps"
    with pytest.raises(MapFileError, match=r"--save-maps .*Lyon.yaml: is also written by --json"):
        check_run_outputs(sc, "scene1", None, maps / "Lyon.yaml", maps)
    check_run_outputs(sc, "scene1", tmp_path / "r.rrd", tmp_path / "r.json", maps, None, tmp_path / "r.png")
    assert not maps.exists()  # a check creates nothing


def test_no_output_is_the_bag_or_inside_it(sc, tmp_path):
    bag = tmp_path / "bag"
    with pytest.raises(UsageError, match=r"--json .*bag/r.json: is inside the --bag folder"):
        check_run_outputs(sc, "scene1", None, bag / "r.json", None, bag)
    with pytest.raises(UsageError, match=r"--save-maps .*bag: is also written by --bag"):
        check_run_outputs(sc, "scene1", None, None, bag, bag)
    check_run_outputs(sc, "scene1", tmp_path / "r.rrd", None, None, bag)  # beside it: fine


def test_a_bag_must_be_a_new_path(tmp_path):
    (tmp_path / "old").mkdir()
    with pytest.raises(UsageError, match=r"--bag .*old: already exists \(a ROS 2 bag is a folder"):
        check_bag_output(tmp_path / "old")
    (tmp_path / "f").write_text("x")
    with pytest.raises(UsageError, match=r"--bag .*f/new: cannot write the bag here \(.*is not a folder\)"):
        check_bag_output(tmp_path / "f" / "new")
    check_bag_output(tmp_path / "new" / "bag")
    assert not (tmp_path / "new").exists()


def test_the_maps_folder_and_make_folders(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(UsageError, match=r"--save-maps .*f: cannot write there \(not a folder\)"):
        check_maps_folder(tmp_path / "f")
    check_maps_folder(tmp_path / "m" / "n")
    assert not (tmp_path / "m").exists()
    make_folders(None, tmp_path / "m" / "n", tmp_path / "o")
    assert (tmp_path / "m" / "n").is_dir() and (tmp_path / "o").is_dir()
    with pytest.raises(UsageError, match=r"f/sub: cannot make the folder \("):
        make_folders(tmp_path / "f" / "sub")
