"""The rotation × translation search (merger.search) against ground truth.

x_ref = c_ref + t + R(θ)(x_mov − c_mov), t within ±window_m in one-cell steps. Checked here:

* W = 0 is the thesis's rotation-only search bit for bit (a yardstick written out in this file);
* the window's parameters and their errors;
* the fast windowed method against the exhaustive reference on fixed seeds (the property tests over
  arbitrary grids are in tests/merger/search/test_engine.py);
* recovery of (θ*, t*) with rough centers on generated rooms and on the real office map, and in a team
  merge (where the rotation-only search fails with the same center errors);
* the grid answer (refine=False) and the bounds of the sub-cell refinement.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import strategies as st

import merger
from merger import load_map
from merger.grid import OccupancyGrid
from merger.lattice import extract_roi, roi_cells, rotated_roi
from merger.measures import measure_fn
from merger.search import (
    MAX_WINDOW_FRACTION,
    RotationProblem,
    angle_diff_deg,
    check_window,
    search,
    searcher_for,
    translation_offsets,
    window_cells,
    wrap_deg,
)
from merger.search import (
    exact_runner_up as exact_window_runner_up,
)
from merger.synthetic import (
    arc_viewpoints,
    partial_view_of_grid,
    random_view_pair,
    robot_pose_on_circle,
    widest_free_point,
    window_case,
    world_to_frame,
)
from merger.team.frames import place_on_frame0
from merger.team.orders import MapInput, MergeParams, merge_team
from merger.team.verify import verify
from merger.transform import rotation
from tests.paths import REAL_MAP
from tests.strategies import three_views

REAL = REAL_MAP

MEASURES = ("similarity", "birk_carpin", "ncc")
RES = 0.05


def close_to_zero_deg(theta: float) -> bool:
    return theta == 0.0 or abs(theta) <= 1e-6 or abs(theta - 360.0) <= 1e-6


def on_grid(x: float, step: float, tol: float = 1e-9) -> bool:
    return abs(x / step - round(x / step)) <= tol


# --- 1. W = 0 is the thesis's search ----------------------------------------------------------------
def thesis_search(ref, mov, c_ref, c_mov, roi_m, measures):
    """The thesis's search (3.3.1) written out: 1° steps over [0, 360), then 0.1° over ±1° of the best
    coarse angle, first maximum on ties; the ROIs by the transform module's own functions. Returns
    {measure: (θ, Similarity)}."""
    n = roi_cells(roi_m, ref.resolution)
    r = extract_roi(ref, c_ref, n)
    rois = {}

    def mov_roi(a):
        if a not in rois:
            rois[a] = rotated_roi(mov, a, c_mov, c_ref, n, ref.resolution)
        return rois[a]

    out = {}
    for m in measures:
        fn = measure_fn(m)
        coarse = [fn(r, mov_roi(float(a))).value for a in range(360)]
        c = int(np.argmax(coarse))
        best = None
        for k in range(-10, 11):
            a = float(c + k * 0.1)
            s = fn(r, mov_roi(a))
            if best is None or s.value > best[1].value:
                best = (a, s)
        out[m] = (wrap_deg(best[0]), best[1])
    return out


@pytest.mark.parametrize("seed", [2, 13, 21])
def test_window_zero_is_the_thesis_search_bit_for_bit(seed):
    ga, ca, gb, cb, roi = random_view_pair(seed)
    roi = min(roi, 5.0)  # the yardstick above is plain numpy: keep it quick
    want = thesis_search(ga, gb, ca, cb, roi, MEASURES)
    for m in MEASURES:
        theta, sim = want[m]
        plain = RotationProblem(ga, gb, ca, cb, roi, m, 0.0)  # the defaults but the window: the thesis's
        zero = RotationProblem(ga, gb, ca, cb, roi, m, window_m=0, refine=False)
        sub_cell = RotationProblem(ga, gb, ca, cb, roi, m, window_m=0.6 * RES, refine=False)  # K = 0
        assert sub_cell.window_cells == 0
        results = [search(zero, "reference"), search(zero, "fast"), search(plain, "reference"),
                   search(plain, "fast"), search(sub_cell, "fast"),
                   merger.search_pair(ga, gb, center_ref=ca, center_moving=cb, roi_m=roi, measure=m, window_m=0,
                                refine=False)]
        for al in results:
            assert (al.theta_deg, al.score, al.counts) == (theta, sim.value, sim.counts), (seed, m, al.method)
            assert al.translation_m == (0.0, 0.0) and al.cells == (0, 0)
            assert al.theta_grid_deg == al.theta_deg and al.translation_grid_m == (0.0, 0.0)
            assert not al.refined


# --- 2. the window's parameters -----------------------------------------------------------------------
def test_translation_offsets_order():
    assert translation_offsets(0) == [(0, 0)]
    assert translation_offsets(1) == [(0, 0), (0, -1), (-1, 0), (1, 0), (0, 1),
                                      (-1, -1), (1, -1), (-1, 1), (1, 1)]
    ts = translation_offsets(2)
    assert ts[:9] == translation_offsets(1)
    assert ts[9:13] == [(0, -2), (-2, 0), (2, 0), (0, 2)]  # a² + b² = 4, then by b, then by a
    assert ts[13:17] == [(-1, -2), (1, -2), (-2, -1), (2, -1)]  # a² + b² = 5 ...
    assert ts[-4:] == [(-2, -2), (2, -2), (-2, 2), (2, 2)]
    for k in (3, 7):
        ts = translation_offsets(k)
        assert len(ts) == len(set(ts)) == (2 * k + 1) ** 2
        assert set(ts) == {(a, b) for a in range(-k, k + 1) for b in range(-k, k + 1)}
        keys = [(a * a + b * b, b, a) for a, b in ts]
        assert keys == sorted(keys)


@pytest.mark.parametrize("window_m, res, k", [
    (0.0, 0.05, 0), (0.049, 0.05, 0), (0.05, 0.05, 1), (0.099, 0.05, 1), (0.15, 0.05, 3), (0.3, 0.05, 6),
    (0.5, 0.05, 10), (0.5, 0.1, 5), (0.7, 0.1, 7), (1.0, 0.025, 40), (0.35, 0.05, 7),
])
def test_window_cells(window_m, res, k):
    assert window_cells(window_m, res) == k  # 0.15 / 0.05 = 2.9999999999999996 is 3 cells


def test_problem_window_cells_uses_the_reference_resolution():
    g = OccupancyGrid(np.zeros((10, 10), np.uint8), 0.1)
    h = OccupancyGrid(np.zeros((10, 10), np.uint8), 0.05)
    assert RotationProblem(g, h, (0, 0), (0, 0), 4.0, window_m=0.5).window_cells == 5
    assert RotationProblem(h, g, (0, 0), (0, 0), 4.0, window_m=0.5).window_cells == 10


@pytest.mark.parametrize("window_m, needle", [
    (-0.1, "window_m must be a finite number >= 0, got -0.1"),
    (-1e-300, "window_m must be a finite number >= 0"),
    (float("nan"), "window_m must be a finite number >= 0, got nan"),
    (float("inf"), "window_m must be a finite number >= 0, got inf"),
    (float("-inf"), "window_m must be a finite number >= 0, got -inf"),
    (1.01, "window_m = 1.01 m is more than a quarter of the ROI side (4 m): expected at most 1 m"),
    (3.0, "expected at most 1 m"),
    ("abc", "window_m must be a number of metres, got 'abc'"),
    (None, "window_m must be a number of metres, got None"),
])
def test_bad_windows_are_value_errors_naming_window_m_and_the_bound(window_m, needle):
    for make in (lambda: check_window(window_m, 4.0), lambda: MergeParams(roi_m=4.0, window_m=window_m),
                 lambda: RotationProblem(OccupancyGrid(np.zeros((4, 4), np.uint8)),
                                         OccupancyGrid(np.zeros((4, 4), np.uint8)), (0, 0), (0, 0), 4.0,
                                         window_m=window_m)):
        with pytest.raises(ValueError) as e:
            make()
        assert needle in str(e.value) and "window_m" in str(e.value), str(e.value)


def test_windows_up_to_a_quarter_of_the_roi_are_allowed():
    for roi, w in ((4.0, 1.0), (8.0, 2.0), (8.0, 0.5), (2.0, 0.5), (3.3, 3.3 / 4), (4.0, 0.0)):
        check_window(w, roi)
        assert MergeParams(roi_m=roi, window_m=w).window_m == w
        # the exported bound (the CLI's message reads it) is the one the check applies, and it is sharp
        check_window(MAX_WINDOW_FRACTION * roi, roi)
        with pytest.raises(ValueError, match="more than a quarter of the ROI side"):
            check_window(roi / 4 + 1e-9, roi)
    assert MergeParams().window_m == 0.5 and MergeParams().refine  # the defaults
    with pytest.raises(ValueError, match="window_m"):
        MergeParams(roi_m=1.9)  # the default window 0.5 m is more than 1.9 / 4


@pytest.mark.parametrize("which", ["center_ref", "center_moving"])
@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_problem_with_non_finite_centers_is_a_value_error(which, bad):
    g = OccupancyGrid(np.zeros((4, 4), np.uint8))
    for c in ((bad, 0.0), (0.0, bad)):
        kw = {"center_ref": (0.0, 0.0), "center_moving": (0.0, 0.0), which: c}
        with pytest.raises(ValueError, match=which):
            RotationProblem(g, g, kw["center_ref"], kw["center_moving"], 4.0, window_m=0.5)
        with pytest.raises(ValueError):
            merger.search_pair(g, g, center_ref=kw["center_ref"], center_moving=kw["center_moving"], roi_m=4.0)


# --- 3. the exact evaluator ----------------------------------------------------------------------------
def _snap(c, origin, mode):
    """A center on a cell corner / a cell centre of the lattice of ``origin`` (or as given)."""
    if mode == "given":
        return tuple(float(v) for v in c)
    off = 0.0 if mode == "corner" else 0.5
    return tuple(float(o + (math.floor((v - o) / RES) + off) * RES) for v, o in zip(c, origin, strict=True))


def _angles(rng):
    """Random angles, integers, right angles and values of the 0.1° grid (as fine_angles builds them)."""
    fine = [float(x) for x in int(rng.integers(0, 360)) + np.arange(-10, 11) * 0.1]
    return [float(rng.uniform(0, 360)), float(rng.uniform(0, 360)), float(rng.integers(1, 360)),
            0.0, 90.0, 180.0, 270.0, 359.9, fine[int(rng.integers(0, 21))], fine[3], 89.9, 0.1]


def _translations(rng, k, reach):
    ts = {(0, 0), (k, k), (-k, -k), (k, -k), (-k, k), (reach, -reach)}
    while len(ts) < 14:
        ts.add(tuple(int(v) for v in rng.integers(-k, k + 1, 2)))
    return sorted(ts)






def _random_grid(rng, shape, res, origin):
    p = rng.dirichlet([1.0, 1.0, 1.0])
    return OccupancyGrid(rng.choice(3, size=shape, p=p).astype(np.uint8), res, origin)


def _point(rng, origin, cells, mode, res):
    """A point at cell index ``cells`` (per axis) of the lattice of ``origin``: anywhere in the cell, or
    exactly on its corner, its centre or an edge midpoint (lookups on cell borders)."""
    frac = {"random": rng.random(2), "corner": np.zeros(2), "center": np.full(2, 0.5),
            "edge": np.array([0.0, 0.5])[rng.permutation(2)]}[mode]
    return tuple(float(o + (i + f) * res) for o, i, f in zip(origin, cells, frac, strict=True))


SMALL = dict(seed=st.integers(0, 2**32 - 1), n=st.integers(4, 40), measure=st.sampled_from(MEASURES),
             mres=st.sampled_from([0.05, 0.05, 0.1, 0.04]), round_origin=st.booleans(),
             modes=st.tuples(*[st.sampled_from(["random", "corner", "center", "edge"])] * 2),
             theta=st.one_of(st.floats(0.0, 360.0, exclude_max=True),
                             st.sampled_from([0.0, 90.0, 180.0, 270.0, 45.0, 359.9, 0.1, 1.0, 123.0]),
                             st.integers(0, 3599).map(lambda k: k * 0.1), st.integers(0, 359).map(float)))


def _small_problem(seed, n, measure, mres, round_origin, modes, *, ref_holds_the_window: bool):
    rng = np.random.default_rng(seed)

    def origin():
        o = rng.uniform(-2.0, 0.5, 2)
        return tuple(float(v) for v in (np.round(o / RES) * RES if round_origin else o))

    roi = n * RES
    k_max = window_cells(roi / 4, RES)
    w = float(rng.integers(0, k_max + 1)) * RES if rng.random() < 0.5 else float(rng.uniform(0, roi / 4))
    k = window_cells(w, RES)
    mov = _random_grid(rng, tuple(rng.integers(20, 41, 2)), mres, origin())
    cm = _point(rng, mov.origin, rng.integers(-4, np.array(mov.shape[::-1]) + 4), modes[1], mres)
    if ref_holds_the_window:  # every ROI lattice about c_ref + t, |a|, |b| ≤ K + 1, lies inside the grid
        lo = n // 2 + k + 3
        shape = tuple(int(v) for v in rng.integers(20, 41, 2) + 2 * lo)
        ref = _random_grid(rng, shape, RES, origin())
        cells = [rng.integers(lo, size - lo) for size in shape[::-1]]
    else:  # anywhere: the grid may be narrower than the ROI, the center near or beyond its border
        ref = _random_grid(rng, tuple(rng.integers(20, 41, 2)), RES, origin())
        cells = rng.integers(-4, np.array(ref.shape[::-1]) + 4)
    cr = _point(rng, ref.origin, cells, modes[0], RES)
    p = RotationProblem(ref, mov, cr, cm, roi, measure, w)
    assert p.window_cells == k
    ts = [(a, b) for a in range(-k - 1, k + 2) for b in range(-k - 1, k + 2)]  # the window and one beyond
    if len(ts) > 50:
        ts = [ts[i] for i in rng.choice(len(ts), 50, replace=False)]
    return p, ts


def _inside(p, ts) -> bool:
    ref = p.ref
    for a, b in ts:
        c = p.center_at(a, b)
        for ax, size in ((0, ref.width), (1, ref.height)):
            idx = np.floor((c[ax] + np.array([-1, 1]) * (p.n - 1) / 2.0 * RES - ref.origin[ax]) / RES)
            if idx.min() < 0 or idx.max() >= size:
                return False
    return True










# The ROI lattice about c_ref + t leaving the reference grid (a reference grid narrower than the ROI plus
# the window, or a center near its border): the evaluator once returned wrong values or raised there (its
# crop of reference-occupied cells and its margin came from the clipped lattice); these are the minimal
# cases that showed it.
def _twenty_by_twenty():
    rng = np.random.default_rng(0)
    g = [OccupancyGrid(rng.choice(3, size=(20, 20)).astype(np.uint8), 0.05, (0.0, 0.0)) for _ in range(2)]
    return g[0], g[1]




def test_windowed_search_on_a_map_smaller_than_the_roi():
    """merger.align with its defaults (ROI 8 m, window 0.5 m) on a 5 m × 5 m map (a robot's early map):
    the exhaustive reference handles it (unknown outside the grid); the fast method must agree."""
    s = np.ones((100, 100), np.uint8)
    s[::7, ::5] = 2
    g = OccupancyGrid(s, 0.05)
    p = RotationProblem(g, g, (2.5, 2.5), (2.5, 2.5), 8.0, "similarity", 0.5)
    al = merger.search_pair(g, g, center_ref=(2.5, 2.5))
    assert close_to_zero_deg(al.theta_deg) and max(map(abs, al.translation_m)) <= 1e-9
    grid = search(p, "fast")
    assert grid.score == 1.0 and grid.translation_m == (0.0, 0.0)


# --- 4. fast vs the exhaustive reference -------------------------------------------------------------
REF_CASES = [("views", 0, "similarity"), ("views", 1, "similarity"), ("views", 2, "similarity"),
             ("identical", 0, "similarity"), ("identical", 2, "similarity"), ("sparse", 0, "similarity"),
             ("sparse", 1, "similarity"), ("sparse", 2, "similarity"), ("identical", 1, "birk_carpin"),
             ("sparse", 3, "birk_carpin"), ("noise", 0, "similarity"), ("symmetric", 18, "similarity")]


def _ref_problem(kind, seed, measure):
    c = window_case(seed, kind, roi_m=(3.2, 4.0), window_m=(0.15, 0.3))
    p = RotationProblem(c.ref, c.moving, c.center_ref, c.center_moving, c.roi_m, measure, c.window_m)
    assert p.window_cells >= 3
    return p


def assert_same_window_answer(p, ref, fast):
    assert (fast.theta_deg, fast.translation_m, fast.cells, fast.score) == \
        (ref.theta_deg, ref.translation_m, ref.cells, ref.score)
    assert fast.counts == ref.counts
    assert (ref.method, fast.method) == ("reference", "fast") and not fast.refined
    # the reference's score is the exact value of its answer, within the window
    a, b = ref.cells
    assert ref.score == p.at(a, b).evaluate(ref.theta_deg).value
    assert max(abs(a), abs(b)) <= p.window_cells


@pytest.mark.parametrize("kind, seed, measure", REF_CASES)
def test_fast_window_search_equals_the_reference(kind, seed, measure):
    p = _ref_problem(kind, seed, measure)
    assert_same_window_answer(p, search(p, "reference"), search(p, "fast"))


def test_fast_window_search_with_ncc():
    """NCC through the windowed fast search (its approximate stage once read a correlation that does not
    exist and raised IndexError on every NCC search with a window)."""
    p = _ref_problem("views", 1, "ncc")
    assert_same_window_answer(p, search(p, "reference"), search(p, "fast"))


# --- 5. a map against itself ---------------------------------------------------------------------------
def _self_cases():
    out = []
    for seed in (0, 1, 4):
        ga, ca, gb, cb, _ = random_view_pair(seed)
        out += [(ga, ca), (gb, cb)]
    w = window_case(1, "identical")
    out.append((w.ref, w.center_ref))
    g, c = out[0]
    out.append((g, (round(c[0], 1), round(c[1], 1))))  # a center on a cell corner: border ties at 0°
    return out


def test_a_map_aligned_with_itself_is_the_identity():
    grid_not_zero = 0
    for g, c in _self_cases():
        for roi in (8.0, 4.0):
            al = merger.search_pair(g, g, center_ref=c, roi_m=roi)  # fast, window 0.5 m, refined
            assert al.refined and al.window_m == 0.5
            assert close_to_zero_deg(al.theta_deg), (c, roi, al.theta_deg)
            assert max(abs(v) for v in al.translation_m) <= 1e-9, al.translation_m
            grid = merger.search_pair(g, g, center_ref=c, roi_m=roi, refine=False)
            assert grid.score == 1.0 and grid.translation_m == (0.0, 0.0)
            assert abs(angle_diff_deg(grid.theta_deg, 0.0)) <= 1.0  # the plateau of equal scores about 0°
            assert (al.theta_grid_deg, al.translation_grid_m) == (grid.theta_deg, grid.translation_m)
            grid_not_zero += grid.theta_deg != 0.0
    assert grid_not_zero > 0  # the grid answer is often 359.x (the first of the plateau): refined, it is 0


# --- 6. recovery with rough centers --------------------------------------------------------------------
# Seeds 0–11 of both kinds: none of them has its best hypothesis at the 180° ambiguity (in a scan of seeds
# 0–199 at this operating point none of "views" and none of "sparse" did; four "sparse" seeds — 19, 31,
# 117, 165 — end 0.51–1.9° off and are left out: see the report of this test file).
RECOVERY = [(kind, seed) for kind in ("views", "sparse") for seed in range(12)]


@pytest.mark.parametrize("kind, seed", RECOVERY)
def test_rotation_and_translation_recovered_with_a_rough_center(kind, seed):
    c = window_case(seed, kind, roi_m=(8.0, 8.0), window_m=(0.5, 0.5), error_frac=0.8)
    assert max(abs(v) for v in c.error_m) <= 0.4
    p = RotationProblem(c.ref, c.moving, c.center_ref, c.center_moving, 8.0, "similarity", 0.5, True)
    al = search(p, "fast")
    assert abs(angle_diff_deg(al.theta_deg, c.theta_deg)) <= 0.5, (al.theta_deg, c.theta_deg)
    assert math.dist(al.translation_m, c.translation_m) <= 0.05, (al.translation_m, c.translation_m)
    assert al.beyond is None  # the truth is inside the window: the guard finds nothing better outside


# The guard beyond the window: "views" seeds with the moving center off by up to 1.8 × the window per axis.
@pytest.mark.slow
def test_the_guard_finds_the_truth_outside_the_window():
    """Every case whose true translation lies outside ±0.5 m but inside the guard's ±1.0 m (less a cell),
    and whose in-window answer is therefore another peak (more than 10° or 0.2 m from the truth): the
    guard reports the truth (θ within 1°, t within 0.1 m), exactly valued, above the in-window best."""
    checked = 0
    for seed in range(24):
        c = window_case(seed, "views", roi_m=(8.0, 8.0), window_m=(0.5, 0.5), error_frac=1.8)
        if not 0.5 < max(abs(v) for v in c.translation_m) <= 0.95:
            continue
        p = RotationProblem(c.ref, c.moving, c.center_ref, c.center_moving, 8.0, "similarity", 0.5, True)
        al = search(p, "fast")
        if abs(angle_diff_deg(al.theta_deg, c.theta_deg)) <= 10.0 and math.dist(al.translation_m,
                                                                                c.translation_m) <= 0.2:
            continue  # the in-window answer is the truth's own peak, cut by the window's edge
        checked += 1
        assert al.beyond is not None, seed
        th, t, v = al.beyond
        assert abs(angle_diff_deg(th, c.theta_deg)) <= 1.0, (seed, th, c.theta_deg)
        assert math.dist(t, c.translation_m) <= 0.1, (seed, t, c.translation_m)
        # exact in what it reports: the value at (θ, t) on the wider window, above the in-window best
        wide = RotationProblem(c.ref, c.moving, c.center_ref, c.center_moving, 8.0, "similarity", 1.0)
        cells = tuple(int(round(x / 0.05)) for x in t)
        assert max(abs(x) for x in cells) > p.window_cells
        assert searcher_for(wide).values(th, [cells])[0] == v
        assert v > al.profile.max() - 1e-12
    assert checked >= 12, checked  # 16 of the 24 seeds


@pytest.mark.parametrize("seed", [0, 4, 10])
def test_the_guards_finding_is_bounded_by_the_exhaustive_one(seed):
    """On small problems: whatever the fast guard reports, the exhaustive one (the reference search's
    ``beyond``: the best coarse (θ, t) of the whole ring between the window and twice it) reports too,
    scoring at least as much. (The exhaustive one also reports weak peaks the fast guard does not climb.)"""
    c = window_case(seed, "views", roi_m=(2.4, 2.4), window_m=(0.2, 0.2), error_frac=1.8)
    p = RotationProblem(c.ref, c.moving, c.center_ref, c.center_moving, 2.4, "similarity", 0.2)
    fast, ref = search(p, "fast"), search(p, "reference")
    assert (fast.theta_deg, fast.cells) == (ref.theta_deg, ref.cells)
    assert fast.beyond is not None and ref.beyond is not None
    assert ref.beyond[2] >= fast.beyond[2] > ref.profile.max()


def test_without_the_window_the_same_rough_centers_cost_the_rotation():
    """The control of the test above: the rotation-only search (window 0) of the same problems, whose
    translation is 0 by construction, also misses the rotation by more than 0.5° on most of them (the
    misplaced center smears the ROI: 0.08–22° here, 69° on sparse seed 6)."""
    errors = []
    for kind, seed in RECOVERY[::3]:
        c = window_case(seed, kind, roi_m=(8.0, 8.0), window_m=(0.5, 0.5), error_frac=0.8)
        al = merger.search_pair(c.ref, c.moving, center_ref=c.center_ref, center_moving=c.center_moving, window_m=0.0)
        assert al.translation_m == (0.0, 0.0)
        errors.append(abs(angle_diff_deg(al.theta_deg, c.theta_deg)))
    assert sum(e > 0.5 for e in errors) >= 6, errors


def _whole_map_checks(c, hypotheses):
    """Whole-map verification (merge_team's rule) of (θ, t) hypotheses of c.moving onto c.ref."""
    maps = [MapInput("a", c.ref, c.center_ref), MapInput("b", c.moving, c.center_moving)]
    params = MergeParams()
    out = []
    for theta, t in hypotheses:
        lay = place_on_frame0(maps, {0: (0.0, (0.0, 0.0)), 1: (theta, tuple(t))})
        out.append(verify(lay[0].states, lay[1].states, nu_min=params.nu_min, min_support=params.min_support))
    return out


def test_a_half_turn_of_a_point_symmetric_scene_is_not_told_apart_by_verification():
    """The "symmetric" kind (a point-symmetric room, no boxes, seen over a short arc): seed 2's best ROI
    hypothesis is the 180° one (so are seeds 17, 19, 23–26 of 0–29). The scene itself is point-symmetric,
    so whole-map verification passes it as well as the truth: the ambiguity is the scene's. Recorded as
    it is (not a requirement on the search)."""
    c = window_case(2, "symmetric", roi_m=(8.0, 8.0), window_m=(0.5, 0.5))
    p = RotationProblem(c.ref, c.moving, c.center_ref, c.center_moving, 8.0, "similarity", 0.5, True)
    al = search(p, "fast")
    assert abs(angle_diff_deg(al.theta_deg, c.theta_deg + 180.0)) <= 0.5
    v_true, v_flip = _whole_map_checks(c, [(c.theta_deg, c.translation_m), (al.theta_deg, al.translation_m)])
    assert v_true.passed and v_flip.passed, (v_true, v_flip)


@pytest.mark.parametrize("kind, seed", [("views", 3), ("views", 8), ("views", 10)])
def test_a_half_turn_with_a_rough_center_fails_whole_map_verification(kind, seed):
    """A room with walls off the center (not point-symmetric): the best (θ, t) near the half turn — by the
    exact evaluator over the whole window, θ* + 180° ± 4° — fails the whole-map verification that the
    truth passes. (No "views"/"sparse" seed of the recovery test has its best hypothesis there. The
    "sparse" kind is not used here: its true alignments fail whole-map verification too, ν = 0.19–0.39
    for seeds 0–11 — pillars and boxes without walls give little whole-map agreement.)"""
    c = window_case(seed, kind, roi_m=(8.0, 8.0), window_m=(0.5, 0.5))
    p = RotationProblem(c.ref, c.moving, c.center_ref, c.center_moving, 8.0, "similarity", 0.5)
    ev = searcher_for(p)
    k = p.window_cells
    ts = [(a, b) for a in range(-k, k + 1) for b in range(-k, k + 1)]
    flip = round(c.theta_deg + 180.0)
    best = max((float(v), float(th % 360), ts[i]) for th in range(flip - 4, flip + 5)
               for i, v in enumerate(ev.values(float(th % 360), ts)))
    verdicts = _whole_map_checks(c, [(c.theta_deg, c.translation_m), (best[1], p.offset_m(*best[2]))])
    assert verdicts[0].passed and not verdicts[1].passed, verdicts


OFFICE_E = [(0.3, -0.2), (-0.4, 0.1)]


@pytest.fixture(scope="module")
def office():
    return load_map(REAL)


def _office_pair(office, where, yaw_offsets, arc):
    if where == "upper":
        center, clearance = widest_free_point(office)
        radius = min(0.8 * clearance, 1.8)
    else:
        center, radius = (-1.825, -2.825), 1.0
    out = []
    for a, off in zip((90.0, 210.0), yaw_offsets, strict=True):
        pose = robot_pose_on_circle(a, radius, center, off)
        g = partial_view_of_grid(office, pose, arc_viewpoints(a, arc, radius, center))
        out.append((pose, g, tuple(float(v) for v in world_to_frame(center, pose))))
    return out


@pytest.mark.parametrize("where, yaws, arc", [("upper", (0.0, 17.0), 15.0), ("upper", (-25.0, 140.0), 30.0),
                                              ("lower", (10.0, -33.0), 15.0), ("lower", (0.0, 17.0), 30.0)])
def test_rough_center_recovered_on_real_map_views(office, where, yaws, arc):
    (p1, g1, c1), (p2, g2, c2) = _office_pair(office, where, yaws, arc)
    truth = math.degrees(p2[2] - p1[2]) % 360
    for e in OFFICE_E:
        cm = (c2[0] + e[0], c2[1] + e[1])
        al = merger.search_pair(g1, g2, center_ref=c1, center_moving=cm)  # fast, ROI 8 m, window 0.5 m, refined
        want_t = rotation(truth) @ np.asarray(e)
        assert abs(angle_diff_deg(al.theta_deg, truth)) <= 0.5, (e, al.theta_deg, truth)
        assert math.dist(al.translation_m, want_t) <= 0.05, (e, al.translation_m, want_t)


# --- 7. the grid answer and the refinement's bounds ----------------------------------------------------
def _grid_cases():
    out = [window_case(s, k, roi_m=(8.0, 8.0), window_m=(0.5, 0.5)) for k, s in
           (("views", 0), ("views", 5), ("sparse", 2), ("sparse", 6))]
    # the truth beyond the window (error 1.6 × W): the grid answer on the window's edge
    out.append(window_case(4, "views", roi_m=(6.0, 6.0), window_m=(0.3, 0.3), error_frac=1.6))
    return out


def test_each_method_names_how_exact_its_profile_and_runner_up_are():
    """Alignment.evidence (runner-up and profile exact, or named an envelope in the API): the reference
    exact; fast an upper-envelope profile (never above the best coarse value) and its runner-up (at
    least the reference's score, never above the best); the exact runner-up on demand equals the
    reference's. The JSON record carries it."""
    c = _grid_cases()[0]
    want = {("reference", 0.0): ("exact", "exact"), ("fast", 0.0): ("upper_envelope", "upper_envelope"),
            ("reference", 0.2): ("exact", "exact"), ("fast", 0.2): ("upper_envelope", "upper_envelope")}
    roi = 3.2  # a small ROI: the windowed reference stays cheap
    for (method, w), (profile, ru) in want.items():
        p = RotationProblem(c.ref, c.moving, c.center_ref, c.center_moving, roi, "similarity", w, refine=False)
        al = search(p, method)
        assert al.evidence == {"profile": profile, "runner_up": ru}, (method, w)
        assert al.to_dict()["evidence"] == al.evidence
        if method == "fast":
            ref = search(p, "reference")
            assert exact_window_runner_up(p, al.theta_deg) == ref.runner_up
            assert ref.runner_up[1] <= al.runner_up[1] <= al.profile.max()
            assert np.all(al.profile >= ref.profile) and np.all(al.profile <= ref.profile.max())


def test_grid_answer_and_refinement_bounds():
    moved = edge = 0
    for c in _grid_cases():
        args = (c.ref, c.moving, c.center_ref, c.center_moving, c.roi_m, "similarity", c.window_m)
        g = search(RotationProblem(*args, refine=False), "fast")
        r = search(RotationProblem(*args, refine=True), "fast")
        w, res = c.window_m, c.ref.resolution
        k = window_cells(w, res)
        # refine=False: θ on the 0.1° grid, t a whole number of cells within the window
        assert not g.refined and 0.0 <= g.theta_deg < 360.0 and on_grid(g.theta_deg, 0.1)
        assert all(on_grid(v, res) and abs(v) <= k * res + 1e-12 for v in g.translation_m), g.translation_m
        assert g.translation_m == (g.cells[0] * res, g.cells[1] * res)
        assert (g.theta_grid_deg, g.translation_grid_m) == (g.theta_deg, g.translation_m)
        # refine=True keeps the grid answer and moves within ±1° and ±1 cell of it, inside the window
        assert r.refined and (r.theta_grid_deg, r.translation_grid_m, r.cells) == (g.theta_deg, g.translation_m,
                                                                                  g.cells)
        assert 0.0 <= r.theta_deg < 360.0
        assert abs(angle_diff_deg(r.theta_deg, g.theta_deg)) <= 1.0 + 1e-9
        for v, v0 in zip(r.translation_m, g.translation_m, strict=True):
            assert abs(v - v0) <= res + 1e-12 and abs(v) <= w + 1e-12, (r.translation_m, g.translation_m, w)
        moved += r.theta_deg != g.theta_deg or r.translation_m != g.translation_m
        edge += any(abs(v) == k for v in g.cells)
    assert moved >= 3  # the refinement does move below the grid (else the bounds above test nothing)
    assert edge >= 1  # ... and one grid answer lies on the window's edge, where the window bounds it


# --- 8. a team with rough centers ----------------------------------------------------------------------
TEAM_E = [(0.2, -0.15), (-0.25, 0.1), (0.15, 0.25)]  # |e| = 0.25, 0.27, 0.29 m


def _team(seed, errors):
    _, names, maps, truth = three_views(seed)
    inputs = [MapInput(n, g, (c[0] + e[0], c[1] + e[1])) for n, (g, c), e in zip(names, maps, errors,
                                                                                    strict=True)]
    # x_0 = c_0 + R(θ*)(x_k − c_k) with the given centers c'_k = c_k + e_k: t*_0k = R(θ*_0k)·e_k − e_0
    t_true = {n: tuple(rotation(truth[n]) @ np.asarray(e) - np.asarray(errors[0]))
              for n, e in zip(names, errors, strict=True)}
    return names, inputs, truth, t_true


@pytest.mark.parametrize("seed", [3, 11])
def test_team_with_rough_centers_is_merged_with_the_window(seed):
    names, inputs, truth, t_true = _team(seed, TEAM_E)
    res = merge_team(inputs, MergeParams(window_m=0.5))
    assert res.accepted
    ch = res.chosen
    for n in names:
        assert abs(angle_diff_deg(ch.theta_deg[n], truth[n])) <= 0.5, (n, ch.theta_deg[n], truth[n])
        assert math.dist(ch.translation(n), t_true[n]) <= 0.05, (n, ch.translation(n), t_true[n])
    assert ch.translation(names[0]) == (0.0, 0.0) and ch.theta_deg[names[0]] == 0.0


@pytest.mark.parametrize("seed", [3, 11])
def test_team_with_rough_centers_is_rejected_without_the_window(seed):
    """With window_m = 0 (the thesis's search) the same center errors of 0.25–0.29 m leave every map
    misplaced by about that much: the whole-map ν of the misplaced maps falls far below ν_min, so every
    order is rejected (nothing wrong is accepted). With the exact centers the same search is accepted:
    the rejection is the centers' doing."""
    names, inputs, truth, t_true = _team(seed, TEAM_E)
    res = merge_team(inputs, MergeParams(window_m=0.0))
    assert not res.accepted and res.merged is None
    assert all(o.translation(n) == (0.0, 0.0) for o in res.orders for n in names)
    assert min(res.top.nu.values()) < 0.5
    names, exact, truth, _ = _team(seed, [(0.0, 0.0)] * 3)
    ok = merge_team(exact, MergeParams(window_m=0.0))
    assert ok.accepted and max(ok.chosen.angle_errors_deg(truth).values()) <= 0.5


