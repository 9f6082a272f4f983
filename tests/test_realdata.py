"""tests/realdata.py finds the shared real maps where the user keeps them (issue 45, item 9: the path was
hard-coded beside the checkout, so their tests skipped in any other clone, saying only where it looked)."""

from pathlib import Path

from tests import realdata


def test_the_shared_data_folder_comes_from_the_environment(tmp_path):
    assert realdata.data_folder({realdata.ENV: str(tmp_path)}) == tmp_path
    assert realdata.data_folder({realdata.ENV: "~/maps"}) == Path("~/maps").expanduser()
    default = realdata.data_folder({})
    assert default.parts[-3:] == ("shared", "data", "real-maps") and default.parents[2] == Path(__file__).parents[2]


def test_the_skip_reason_says_where_it_looked_and_what_to_set():
    assert str(realdata.DATA) in realdata.MISSING and realdata.ENV in realdata.MISSING
