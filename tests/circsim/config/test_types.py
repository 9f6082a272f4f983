"""circsim.config.types: the typed sections' own behaviour — a rectangular room's four walls close around
its center, the laser's beam angles span its field of view (a full turn without a duplicate beam), the
center errors come from one stream whatever is given per robot, the map thresholds are the merger's,
and every section is frozen."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from circsim.config.types import (
    CenterErrorSpec,
    LaserConfig,
    MapGrid,
    RobotsSpec,
    Room,
    SlamConfig,
    WorldSpec,
)
from merger.grid import DEFAULT_FREE_THRESH, DEFAULT_OCCUPIED_THRESH, FREE_S, OCCUPIED_S, UNKNOWN_S


def test_a_rectangular_rooms_walls_close_around_its_center():
    segs = Room((6.0, 4.0), (1.0, -1.0)).wall_segments()
    assert len(segs) == 4
    for a, b in zip(segs, segs[1:] + segs[:1], strict=True):
        assert a[2:] == b[:2]  # each wall ends where the next begins
    xs = [v for s in segs for v in (s[0], s[2])]
    ys = [v for s in segs for v in (s[1], s[3])]
    assert (min(xs), max(xs), min(ys), max(ys)) == (-2.0, 4.0, -3.0, 1.0)
    assert Room((2.0, 2.0)).wall_segments()[0] == (-1.0, -1.0, 1.0, -1.0)  # no center: about (0, 0)
    walls = ((0.0, 0.0, 1.0, 0.0),)
    assert Room(None, None, walls).wall_segments() == walls


@settings(max_examples=60, deadline=None)
@given(fov=st.floats(1.0, 360.0), beams=st.integers(2, 2000))
def test_the_beams_span_the_field_of_view(fov, beams):
    cfg = LaserConfig(fov_deg=fov, beams=beams)
    a = cfg.angles()
    assert a.shape == (beams,) and a[0] == pytest.approx(-math.radians(fov) / 2)
    assert a[-1] == pytest.approx(cfg.angle_max)
    assert np.allclose(np.diff(a), cfg.angle_increment)
    if fov >= 360.0:  # a full turn: the last beam stops one step short of the first again
        assert cfg.angle_max + cfg.angle_increment == pytest.approx(cfg.angle_min + 2 * math.pi)
    else:  # symmetric about the heading
        assert cfg.angle_max == pytest.approx(math.radians(fov) / 2)


def test_the_default_laser_is_a_urg_04lx():
    cfg = LaserConfig()
    assert (cfg.fov_deg, cfg.beams, cfg.range_max_m) == (240.0, 667, 5.6)
    assert math.degrees(cfg.angle_increment) == pytest.approx(0.36, abs=1e-3)  # the datasheet's step


def test_center_errors_draw_every_direction_whatever_is_given():
    names = ("A", "B", "C")
    spec = CenterErrorSpec(0.2)
    v = spec.vectors(names, np.random.default_rng(4))
    assert all(math.hypot(*v[n]) == pytest.approx(0.2) for n in names)
    given_b = CenterErrorSpec(0.2, {"B": (0.05, -0.05)}).vectors(names, np.random.default_rng(4))
    assert given_b["B"] == (0.05, -0.05)
    assert given_b["A"] == v["A"] and given_b["C"] == v["C"]  # the others' draws do not move
    assert CenterErrorSpec().vectors(names, np.random.default_rng(0)) == {n: (0.0, 0.0) for n in names}


def test_the_map_thresholds_are_the_mergers():
    s = SlamConfig()
    assert (s.occupied_thresh, s.free_thresh) == (DEFAULT_OCCUPIED_THRESH, DEFAULT_FREE_THRESH)
    assert s.log_odds.miss < 0 < s.log_odds.hit <= s.log_odds.clamp


def test_a_map_grid_is_solid_where_not_free():
    st_ = np.array([[UNKNOWN_S, FREE_S, OCCUPIED_S]], np.uint8)
    assert MapGrid.FREE == FREE_S
    assert MapGrid(st_, 0.05, (0.0, 0.0)).solid.tolist() == [[True, False, True]]


@pytest.mark.parametrize("obj, attr", [(WorldSpec(), "center"), (RobotsSpec(), "radius_m"), (LaserConfig(), "beams"),
                                       (SlamConfig(), "resolution_m"), (Room(), "size_m")])
def test_sections_are_frozen(obj, attr):
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(obj, attr, None)
