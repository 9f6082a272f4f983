import numpy as np
import pytest

from merger.grid import OccupancyGrid
from merger.lattice import extract_roi, rotated_roi
from merger.transform import (
    apply_alignment,
    canvas,
    paste,
    sample_nearest,
    warp_grid,
)

U, F, O = 0, 1, 2


def test_apply_alignment_definition():
    # x_i = c_i + R(θ)(x_j − c_j): 90° maps (1, 0) relative to c_j onto (0, 1) relative to c_i
    p = apply_alignment([[3.0, 2.0]], 90.0, (2.0, 2.0), (10.0, 10.0))
    np.testing.assert_allclose(p, [[10.0, 11.0]], atol=1e-12)


def test_sample_nearest_uses_containing_cell_and_unknown_outside():
    g = OccupancyGrid(np.array([[F, O], [U, F]], np.uint8), 1.0, (0.0, 0.0))
    pts = np.array([[0.5, 0.5], [1.99, 0.01], [0.2, 1.7], [-0.1, 0.5], [2.0, 0.5]])
    assert sample_nearest(g, pts).tolist() == [F, O, U, U, U]


def test_rotation_by_90_degrees_is_exact():
    rng = np.random.default_rng(0)
    s = rng.integers(0, 3, (21, 21)).astype(np.uint8)
    g = OccupancyGrid(s, 0.05, (-0.525, -0.525))  # center (0, 0) at the middle of cell (10, 10)
    for k in range(4):
        w = warp_grid(g, 90.0 * k, (0.0, 0.0), (0.0, 0.0), g)
        # rows grow with y, so a counter-clockwise turn in the world is np.rot90's clockwise turn
        np.testing.assert_array_equal(w.states, np.rot90(s, -k))


def test_roi_crop_and_rotation_identity():
    rng = np.random.default_rng(1)
    g = OccupancyGrid(rng.integers(0, 3, (40, 40)).astype(np.uint8), 0.05, (0.0, 0.0))
    c = (1.0, 1.0)
    np.testing.assert_array_equal(rotated_roi(g, 0.0, c, c, 10, 0.05), extract_roi(g, c, 10))
    np.testing.assert_array_equal(extract_roi(g, c, 10), g.states[15:25, 15:25])
    # a 45° rotation leaves the reference square's corners outside the rotated moving square
    r45 = rotated_roi(g, 45.0, c, c, 10, 0.05)
    assert r45[0, 0] == U and r45[-1, -1] == U


def test_canvas_covers_all_and_paste_keeps_ref():
    ref = OccupancyGrid(np.full((10, 20), O, np.uint8), 0.1, (0.0, 0.0))
    mov = OccupancyGrid(np.full((10, 20), F, np.uint8), 0.1, (0.0, 0.0))
    cv = canvas(ref, [(mov, 90.0, (0.0, 0.0))], (0.0, 0.0))
    x0, x1, y0, y1 = cv.extent
    assert x0 <= -1.0 + 1e-9 and x1 >= 2.0 - 1e-9 and y0 <= 0 and y1 >= 2.0 - 1e-9
    p = paste(ref, cv)
    assert p.count()["occupied"] == ref.count()["occupied"]
    w = warp_grid(mov, 90.0, (0.0, 0.0), (0.0, 0.0), cv)
    assert w.count()["free"] == pytest.approx(200, abs=10)


def test_resample_keeps_walls_and_follows_the_ternary_rule():
    """Coarser: occupied where any occupied cell falls, free where free cells cover at least half, else
    unknown; finer: the state under each new cell's centre; the origin and the extent stay."""
    from merger.grid import FREE_S, OCCUPIED_S, UNKNOWN_S, OccupancyGrid
    from merger.transform import resample

    s = np.zeros((4, 6), np.uint8)
    s[:2, :2] = [[OCCUPIED_S, FREE_S], [FREE_S, FREE_S]]  # one wall cell among free: occupied
    s[:2, 2:4] = [[FREE_S, FREE_S], [UNKNOWN_S, UNKNOWN_S]]  # half free: free
    s[:2, 4:6] = [[FREE_S, UNKNOWN_S], [UNKNOWN_S, UNKNOWN_S]]  # a quarter free: unknown
    s[2:, :] = FREE_S
    g = OccupancyGrid(s, 0.05, (1.0, -2.0))
    c = resample(g, 0.1)
    assert c.shape == (2, 3) and c.resolution == 0.1 and c.origin == g.origin
    assert c.states.tolist() == [[OCCUPIED_S, FREE_S, UNKNOWN_S], [FREE_S, FREE_S, FREE_S]]
    f = resample(c, 0.05)
    assert f.shape == g.shape and np.array_equal(f.states, np.kron(c.states, np.ones((2, 2), np.uint8)))
    assert resample(g, 0.05) is g
    odd = resample(g, 0.07)  # not a whole ratio: round(side x 0.05 / 0.07) cells
    assert odd.shape == (round(4 * 5 / 7), round(6 * 5 / 7)) and (odd.states == OCCUPIED_S).sum() == 1


# issue 37, item 6: a 4224² map's numpy warp held 1.2 GB of working arrays at once (per thread: 3.3 GB for a
# merge of three); it now works through blocks of rows
def _warp_at_once(moving, theta, cm, ct, target):
    """The warp as it was computed before blocks: every target cell at once."""
    rows, cols = np.indices(target.shape)
    pts = apply_alignment(target.cell_center(rows, cols), -theta, ct, cm)
    return sample_nearest(moving, pts)


@pytest.mark.parametrize("theta", [0.0, 33.3, 90.0, 211.7])
def test_the_numpy_warp_in_blocks_is_the_warp_at_once(monkeypatch, theta):
    import merger.transform as T

    rng = np.random.default_rng(int(theta))
    mov = OccupancyGrid(rng.integers(0, 3, (97, 131)).astype(np.uint8), 0.05, (-1.3, 0.7))
    target = OccupancyGrid(np.zeros((113, 89), np.uint8), 0.05, (-2.0, -0.4))
    cm, ct = (0.93, 2.71), (0.2, 1.1)
    want = _warp_at_once(mov, theta, cm, ct, target)
    for cells in (1, 89 * 7 + 3, 1 << 20):  # one row a block, a ragged last block, one block
        monkeypatch.setattr(T, "WARP_BLOCK_CELLS", cells)
        assert np.array_equal(T.warp_grid_numpy(mov, theta, cm, ct, target).states, want)


def test_the_numpy_warp_of_a_large_target_holds_a_block_not_the_map():
    import tracemalloc

    from merger.transform import warp_grid_numpy

    mov = OccupancyGrid(np.ones((300, 300), np.uint8), 0.05, (0.0, 0.0))
    target = OccupancyGrid(np.zeros((2500, 2500), np.uint8), 0.05, (-50.0, -50.0))  # 6.25 M cells
    tracemalloc.start()
    try:
        warp_grid_numpy(mov, 30.0, (7.5, 7.5), (7.5, 7.5), target)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 150 << 20, peak / 2**20  # at once: ~440 MB (8-byte indices, points, cells)
