import numpy as np
import pytest

from merger.grid import FREE_S, OCCUPIED_S, UNKNOWN_S, OccupancyGrid, ros_from_states, states_from_ros


def test_ros_round_trip():
    ros = np.array([[-1, 0, 100], [100, 0, -1]], np.int8)
    g = OccupancyGrid.from_ros(ros, 0.05, (1.0, 2.0))
    assert g.states.tolist() == [[0, 1, 2], [2, 1, 0]]
    np.testing.assert_array_equal(g.to_ros(), ros)


def test_ros_thresholds_like_map_server():
    s = states_from_ros(np.array([-1, 0, 19, 20, 50, 65, 66, 100]))
    assert s.tolist() == [0, 1, 1, 0, 0, 0, 2, 2]


def test_from_probabilities_and_log_odds_agree():
    p = np.array([[np.nan, 0.05, 0.5], [0.9, 0.195, 0.66]])
    g = OccupancyGrid.from_probabilities(p)
    assert g.states.tolist() == [[0, 1, 0], [2, 1, 2]]  # NaN unknown, 0.5 between the thresholds
    lo = np.log(np.nan_to_num(p, nan=0.5) / (1 - np.nan_to_num(p, nan=0.5)))
    assert OccupancyGrid.from_log_odds(lo).states.tolist() == g.states.tolist()


def test_geometry_conventions():
    g = OccupancyGrid.unknown(4, 6, 0.5, (-1.0, 2.0))
    assert g.extent == (-1.0, 2.0, 2.0, 4.0)
    np.testing.assert_allclose(g.cell_center(0, 0), [-0.75, 2.25])
    np.testing.assert_allclose(g.world_to_cell([-0.75, 2.25]), [0.5, 0.5])  # (col, row)
    assert g.count() == {"unknown": 24, "free": 0, "occupied": 0}


def test_rejects_bad_states():
    with pytest.raises(ValueError):
        OccupancyGrid(np.array([[3]], np.uint8))
    with pytest.raises(ValueError):
        OccupancyGrid(np.zeros(4, np.uint8))
    assert ros_from_states(np.array([UNKNOWN_S, FREE_S, OCCUPIED_S])).tolist() == [-1, 0, 100]


def test_known_part_is_the_block_of_known_cells_on_the_same_lattice():
    st = np.zeros((6, 8), np.uint8)
    st[2, 3], st[4, 5] = FREE_S, OCCUPIED_S
    g = OccupancyGrid(st, 0.5, (-1.0, 2.0))
    k = g.known_part()
    assert k.states.tolist() == [[1, 0, 0], [0, 0, 0], [0, 0, 2]]
    assert k.origin == (-1.0 + 3 * 0.5, 2.0 + 2 * 0.5) and k.resolution == 0.5
    assert g.count()["free"] == k.count()["free"] and g.count()["occupied"] == k.count()["occupied"]
    empty = OccupancyGrid.unknown(3, 3)
    assert empty.known_part() is empty
    full = OccupancyGrid(np.ones((2, 2), np.uint8))
    assert full.known_part() is full


def test_public_state_constants_match_the_grid_and_are_apart_from_ros_values():
    """``grid.states == merger.Cell.OCCUPIED`` finds the occupied cells (issue 45, item 5: ``merger.OCCUPIED``
    was ROS's 100 and matched nothing in ``states``); the ROS values are named ``ROS_*`` and are not exported as
    bare UNKNOWN/FREE/OCCUPIED."""
    import merger

    g = OccupancyGrid.from_ros(np.array([[-1, 0, 100]], np.int8))
    assert (g.states == merger.Cell.OCCUPIED).tolist() == [[False, False, True]]
    assert (g.states == merger.Cell.FREE).tolist() == [[False, True, False]]
    assert (g.states == merger.Cell.UNKNOWN).tolist() == [[True, False, False]]
    assert (g.to_ros() == merger.ROS_OCCUPIED).tolist() == [[False, False, True]]
    assert (merger.ROS_UNKNOWN, merger.ROS_FREE, merger.ROS_OCCUPIED) == (-1, 0, 100)
    assert not any(hasattr(merger, n) for n in ("UNKNOWN", "FREE", "OCCUPIED"))
