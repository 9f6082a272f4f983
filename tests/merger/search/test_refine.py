"""merger.search.refine: the sub-cell refinement. Its pieces against brute-force references (the plateau's
middle, the square crop read cell by cell, the blocked bilinear read against numpy's), and its purpose
against ground truth: on generated three-robot scenes whose true rotations are not on the 0.1° grid, the
refined angle stays within ±1° of the grid answer and halves the median error."""

import math

import numpy as np
import pytest

from merger import search_pair
from merger.grid import OccupancyGrid
from merger.search import refine
from merger.search.refine import REFINE_MAX_DEG, _plateau_middle, _remap_mean, square_crop
from tests.strategies import three_views


def test_a_plateau_starts_at_its_middle():
    angles = np.array([9.8, 9.9, 10.0, 10.1, 10.2, 10.3])
    assert _plateau_middle(angles, np.array([0.1, 0.5, 0.5, 0.5, 0.2, 0.5]), 2) == pytest.approx(10.0)
    assert _plateau_middle(angles, np.array([0.1, 0.2, 0.5, 0.5, 0.2, 0.1]), 2) == pytest.approx(10.05)
    assert _plateau_middle(angles, np.array([0.5] * 6), 0) == pytest.approx(10.05)  # the whole run
    assert _plateau_middle(angles, np.array([0.1, 0.2, 0.5, 0.4, 0.2, 0.1]), 2) == 10.0  # a peak: itself


@pytest.mark.parametrize("center, reach", [((0.37, 0.81), 0.3), ((-0.2, -0.1), 0.5), ((2.9, 1.0), 0.4),
                                           ((50.0, 50.0), 0.2)])
def test_square_crop_reads_each_cell_of_the_grid_or_unknown(center, reach):
    rng = np.random.default_rng(3)
    g = OccupancyGrid(rng.integers(0, 3, (40, 60)).astype(np.uint8), 0.05, (-0.5, -0.25))
    crop, org = square_crop(g, center, reach)
    assert crop.shape[0] == crop.shape[1] == math.ceil(2 * reach / 0.05) + 2
    assert org[0] <= center[0] - reach < org[0] + 0.05 + 1e-12  # the crop starts at the cell holding the corner
    for i in range(crop.shape[0]):
        for j in range(crop.shape[1]):
            col = round((org[0] - g.origin[0]) / 0.05) + j
            row = round((org[1] - g.origin[1]) / 0.05) + i
            want = g.states[row, col] if 0 <= row < g.height and 0 <= col < g.width else 0
            assert crop[i, j] == want, (i, j)


def bilinear(field: np.ndarray, x: float, y: float) -> float:
    """field read at pixel coordinates (x, y), bilinear, 0 outside (OpenCV's constant border)."""
    x0, y0 = math.floor(x), math.floor(y)
    total = 0.0
    for dy, wy in ((0, 1 - (y - y0)), (1, y - y0)):
        for dx, wx in ((0, 1 - (x - x0)), (1, x - x0)):
            r, c = y0 + dy, x0 + dx
            if 0 <= r < field.shape[0] and 0 <= c < field.shape[1]:
                total += wx * wy * float(field[r, c])
    return total


def test_the_blocked_bilinear_mean_equals_numpys(monkeypatch):
    rng = np.random.default_rng(5)
    field = rng.random((30, 40)).astype(np.float32)
    mx = rng.uniform(-2, 42, (3, 50)).astype(np.float32)
    my = rng.uniform(-2, 32, (3, 50)).astype(np.float32)
    want = np.array([np.mean([bilinear(field, x, y) for x, y in zip(mx[k], my[k], strict=True)]) for k in range(3)])
    whole = _remap_mean(field, mx, my)
    np.testing.assert_allclose(whole, want, atol=2e-3)  # OpenCV's weights are 1/32 steps (INTER_BITS)
    monkeypatch.setattr(refine, "REMAP_MAX_COLS", 7)  # blocks of 7 points: the sum over blocks is the same
    np.testing.assert_allclose(_remap_mean(field, mx, my), whole, rtol=1e-6)


@pytest.mark.slow
def test_the_refinement_moves_the_angle_towards_the_truth():
    grid_err, fine_err = [], []
    for seed in range(8):
        _, names, maps, truth = three_views(seed)
        (g0, c0), (g1, c1) = maps[0], maps[1]
        al = search_pair(g0, g1, center_ref=c0, center_moving=c1, window_m=0.0)
        assert al.refined and abs((al.theta_deg - al.theta_grid_deg + 180) % 360 - 180) <= REFINE_MAX_DEG + 1e-9

        def err(th, true=truth[names[1]]):
            return abs((th - true + 180) % 360 - 180)

        grid_err.append(err(al.theta_grid_deg))
        fine_err.append(err(al.theta_deg))
    assert max(grid_err) < 0.5  # the grid answer is the right one, on its 0.1 degree grid
    assert np.median(fine_err) < 0.5 * np.median(grid_err), (grid_err, fine_err)
