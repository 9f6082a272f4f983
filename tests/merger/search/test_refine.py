"""merger.search.refine: the sub-cell refinement. Its pieces against brute-force references (the plateau's
middle, the square crop read cell by cell, the blocked bilinear read against numpy's), and its purpose
against ground truth: on generated three-robot scenes whose true rotations are not on the 0.1° grid, the
refined angle stays within ±1° of the grid answer and halves the median error."""

import math

import cv2
import numpy as np
import pytest

from merger import search_pair
from merger.grid import OccupancyGrid
from merger.search.problem import RotationProblem
from merger.search.refine import (
    REFINE_MAX_DEG,
    SUM_BLOCK,
    _block_means,
    _field_reads,
    _pairwise_sum,
    _plateau_middle,
    _smooth_refine,
    square_crop,
)
from tests.strategies import adversarial_problem, three_views


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


def _scene(seed):
    """A field (blurred walls or noise) and points and candidates that read it well inside, on its border and
    outside, a quarter of them on whole and half pixels."""
    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(3, 280, 2))
    if seed % 2:
        field = cv2.GaussianBlur((rng.random((h, w)) < 0.08).astype(np.float32), (0, 0), 1.0)
    else:
        field = rng.random((h, w)).astype(np.float32)
    res = 0.05
    n, m = int(rng.integers(1, 3000)), int(rng.integers(1, 7))
    px = rng.uniform(-0.6, 0.6, n) * max(h, w) * res
    py = rng.uniform(-0.6, 0.6, n) * max(h, w) * res
    px[: n // 4] = np.round(px[: n // 4] / res * 2) * res / 2
    th = np.radians(np.concatenate([[0.0, 90.0], rng.uniform(0, 360, m)]))
    bx, by = rng.uniform(0, w * res, th.size), rng.uniform(0, h * res, th.size)
    return field, px, py, th, bx, by, res


def _coords(px, py, th, bx, by, res):
    """The pixel coordinates the refinement reads at, in float64 and rounded to float32 (its documented formula)."""
    cs, sn = np.cos(th)[:, None], np.sin(th)[:, None]
    mx = ((cs * px - sn * py) + bx[:, None]) / res - 0.5
    my = ((sn * px + cs * py) + by[:, None]) / res - 0.5
    return mx.astype(np.float32), my.astype(np.float32)


@pytest.mark.parametrize("seed", range(6))
def test_the_field_reads_are_bilinear_with_a_zero_border(seed):
    field, px, py, th, bx, by, res = _scene(seed)
    got = _field_reads(field, px, py, np.cos(th), np.sin(th), bx, by, res)
    mx, my = _coords(px, py, th, bx, by, res)
    want = np.array([[bilinear(field, float(x), float(y)) for x, y in zip(mx[k], my[k], strict=True)]
                     for k in range(th.size)])
    assert got.dtype == np.float32
    np.testing.assert_allclose(got, want, rtol=0, atol=3e-6)  # float32 lerps against float64
    inside = (mx >= 0) & (my >= 0) & (mx <= field.shape[1] - 1) & (my <= field.shape[0] - 1)
    whole = inside & (mx == np.round(mx)) & (my == np.round(my))  # on a pixel: that pixel, exactly
    assert np.array_equal(got[whole], field[np.round(my[whole]).astype(int), np.round(mx[whole]).astype(int)])


@pytest.mark.parametrize("seed", range(3))
def test_the_field_reads_are_cv2_remaps_within_its_weights(seed):
    """The reads are what cv2.remap gives (equal bit for bit with OpenCV 5 on a CPU with FMA; older OpenCV
    weighs in 1/32 pixel steps)."""
    field, px, py, th, bx, by, res = _scene(seed)
    mx, my = _coords(px, py, th, bx, by, res)
    want = cv2.remap(field, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    got = _field_reads(field, px, py, np.cos(th), np.sin(th), bx, by, res)
    np.testing.assert_allclose(got, want, rtol=0, atol=float(field.max()) / 32 + 1e-6)


@pytest.mark.parametrize("n", [*range(1, 20), 127, 128, 129, 1000, 4099, 70_001])
def test_the_kernels_sum_is_numpys_pairwise_sum(n):
    rng = np.random.default_rng(n)
    a = (rng.random(n) ** 30 * np.exp(-40 * rng.random(n))).astype(np.float32).astype(np.float64)  # 1e-30 .. 1
    assert _pairwise_sum(a, 0, n) == a.sum()
    assert _pairwise_sum(np.concatenate([[7.0], a]), 1, n) == a.sum()


def test_the_means_are_summed_in_blocks():
    rng = np.random.default_rng(4)
    reads = rng.random((3, 2 * SUM_BLOCK + 123)).astype(np.float32)
    want = np.array([sum(float(v) for v in row) for row in reads.astype(np.float64)]) / reads.shape[1]
    np.testing.assert_allclose(_block_means(reads), want, rtol=1e-12)


@pytest.mark.parametrize("seed", range(8))
def test_the_compiled_pattern_search_is_the_python_one(seed):
    """Adversarial problems (and a windowless one) from starts anywhere in the window: the same (θ, t), bit for
    bit (the same candidates in the same order, the same steps and the same sums)."""
    rng = np.random.default_rng(seed)
    if seed == 7:
        _, _, maps, _ = three_views(seed)
        (g0, c0), (g1, c1) = maps[0], maps[1]
        problems = [RotationProblem(g0, g1, c0, c1, window_m=0.0, refine=True)]
    else:
        problems = [adversarial_problem(seed, measure, window=True) for measure in ("similarity", "ncc")]
    moved = 0
    for prob in problems:
        for _ in range(4):
            w = prob.window_m if prob.window_cells > 0 else 0.0
            start = (float(rng.uniform(0, 360)), (float(rng.uniform(-w, w)), float(rng.uniform(-w, w))))
            got = _smooth_refine(prob, *start)
            assert got == _smooth_refine(prob, *start, kernel=False)
            moved += got != (start[0], start[1])
    assert moved or seed % 5 == 3  # the searches went somewhere (seed 3: near-empty maps, nothing to refine)


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
