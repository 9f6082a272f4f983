"""The fast rotation search returns the reference's answer (property tests on generated scenes).

The reference (merger.search.reference_search) is the yardstick: 360 + 21 whole-ROI rotations. The fast
method (merger.fast) must give the same angle, the same score, the same counts, the same refinement
scores and the same runner-up, for every measure, and the same verdict in a team merge; its profile is
an upper envelope of the reference's. Its building blocks are checked against the reference code paths
on random grids: the sector upper bounds against the exact profile (never below), the exact sparse
evaluator against measure_fn, the separable ROI extraction against extract_roi, and the OpenCV
whole-map warp against the numpy one. The adversarial kinds of ``benchmarks/agree_fast.py`` (noise,
near-empty, identical and lattice-aligned maps, symmetric scenes over short arcs, rough centers) are
sampled here; the script runs thousands of them.
"""

import contextlib
import importlib.util
import math
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import merger
import merger.fast as fast_mod
import merger.sparse as sparse_mod
from merger.fast import SectorBounds, exact_profile, fast_search
from merger.grid import OccupancyGrid
from merger.polar import pool_factor
from merger.search import SEARCH_METHODS, RotationProblem, angle_diff_deg, reference_search
from merger.similarity import measure_fn
from merger.sparse import SparseEvaluator, fast_extract_roi
from merger.synthetic import arc_viewpoints, partial_view, random_view_pair, robot_pose_on_circle, room_scene
from merger.team import MapInput, MergeParams, merge_team
from merger.transform import (
    apply_alignment,
    canvas,
    extract_roi,
    footprint,
    overlap,
    paste,
    warp_grid,
    warp_grid_numpy,
)
from merger.verify import verify

MEASURES = ("similarity", "birk_carpin", "ncc")
_spec = importlib.util.spec_from_file_location("agree_fast", Path(__file__).parents[1] / "benchmarks" / "agree_fast.py")
agree_fast = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(agree_fast)
SPECIAL_ANGLES = (0.0, 90.0, 180.0, 270.0, 45.0, 359.9)


def two_views(seed: int, theta: float, *, arc_shift: float, arc: float, noise: float = 0.002):
    """Two local maps of one generated scene, the second's frame rotated by θ about the center."""
    rng = np.random.default_rng(seed)
    scene = room_scene(rng, n_boxes=int(rng.integers(1, 6)))
    a0 = rng.uniform(0, 360)
    yaw = rng.uniform(0, 2 * math.pi)
    frame_a = (rng.uniform(-1, 1), rng.uniform(-1, 1), yaw)
    frame_b = (rng.uniform(-1, 1), rng.uniform(-1, 1), yaw + math.radians(theta))
    ga, ca = partial_view(scene, frame_a, arc_viewpoints(a0, arc, 1.8, k=3), noise=noise, rng=rng)
    gb, cb = partial_view(scene, frame_b, arc_viewpoints(a0 + arc_shift, arc, 1.8, k=3), noise=noise, rng=rng)
    return ga, ca, gb, cb


def random_grid(rng, shape, res, origin, occupied=0.05, free=0.4):
    """Random states with some structure: blobs of free space and scattered occupied cells."""
    s = (rng.random(shape) < free).astype(np.uint8)
    s[rng.random(shape) < occupied] = 2
    return OccupancyGrid(s, res, origin)


def test_fast_is_registered_and_the_default():
    assert SEARCH_METHODS["fast"] is fast_search
    assert MergeParams().method == "fast"
    import inspect

    assert inspect.signature(merger.align).parameters["method"].default == "fast"


@settings(max_examples=80, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), n=st.integers(1, 90), measure=st.sampled_from(MEASURES),
       mres=st.sampled_from([0.05, 0.05, 0.04, 0.1]), special=st.booleans(),
       theta=st.floats(0.0, 360.0), round_centers=st.booleans(), by_cell=st.booleans())
def test_sparse_evaluator_equals_measure_fn(seed, n, measure, mres, special, theta, round_centers, by_cell):
    """Counts and values at batches of angles equal measure_fn on the reference's own ROIs — the
    moving-occupied counts by shared candidate sets (small ROIs) and cell by cell (large ROIs)."""
    saved = sparse_mod.UNION_MAX_CELLS
    try:
        sparse_mod.UNION_MAX_CELLS = 0 if by_cell else 10**9
        _check_sparse_evaluator(seed, n, measure, mres, special, theta, round_centers)
    finally:
        sparse_mod.UNION_MAX_CELLS = saved


def _check_sparse_evaluator(seed, n, measure, mres, special, theta, round_centers):
    rng = np.random.default_rng(seed)
    ref = random_grid(rng, tuple(rng.integers(20, 120, 2)), 0.05, tuple(rng.uniform(-3, 0, 2)))
    mov = random_grid(rng, tuple(rng.integers(20, 120, 2)), mres, tuple(rng.uniform(-3, 0, 2)))
    cr, cm = rng.uniform(-0.5, 2, 2), rng.uniform(-0.5, 2, 2)
    if round_centers:  # centres on cell corners / centres: many points exactly on cell borders
        cr, cm = np.round(cr, 1), np.round(cm, 1)
    p = RotationProblem(ref, mov, tuple(cr), tuple(cm), n * 0.05, measure)
    ev = SparseEvaluator(p)
    angles = [float(a) for a in (SPECIAL_ANGLES if special else theta + np.arange(-3, 4) * 0.1)]
    values = ev.scores(angles)
    fn = measure_fn(measure)
    for a, v in zip(angles, values, strict=True):
        want = fn(p.ref_roi(), p.moving_roi(a))
        assert v == want.value
        got = ev.similarity(a)
        assert got.value == want.value and got.counts == want.counts
    np.testing.assert_array_equal(ev.ref_roi, p.ref_roi())


@settings(max_examples=30, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), n=st.integers(1, 300), res=st.sampled_from([0.05, 0.1, 0.025]))
def test_fast_extract_roi_equals_extract_roi(seed, n, res):
    rng = np.random.default_rng(seed)
    g = random_grid(rng, tuple(rng.integers(5, 200, 2)), res, tuple(np.round(rng.uniform(-4, 1, 2), 2)))
    c = tuple(np.round(rng.uniform(-5, 5, 2), int(rng.integers(0, 4))))
    np.testing.assert_array_equal(fast_extract_roi(g, c, n), extract_roi(g, c, n))


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), theta=st.floats(0.0, 360.0), special=st.sampled_from((None,) + SPECIAL_ANGLES),
       tres=st.sampled_from([0.05, 0.05, 0.1]), round_geometry=st.booleans())
def test_warp_grid_equals_numpy_version(seed, theta, special, tres, round_geometry):
    """The OpenCV whole-map warp used by team merging gives exactly the numpy (sample_nearest) result."""
    rng = np.random.default_rng(seed)
    digits = 1 if round_geometry else 6
    mov = random_grid(rng, tuple(rng.integers(5, 300, 2)), 0.05, tuple(np.round(rng.uniform(-5, 5, 2), digits)))
    target = OccupancyGrid.unknown(*rng.integers(5, 350, 2), tres, tuple(np.round(rng.uniform(-8, 2, 2), digits)))
    cm, ct = tuple(np.round(rng.uniform(-2, 2, 2), digits)), tuple(np.round(rng.uniform(-2, 2, 2), digits))
    angle = theta if special is None else special
    np.testing.assert_array_equal(warp_grid(mov, angle, cm, ct, target).states,
                                  warp_grid_numpy(mov, angle, cm, ct, target).states)


def _on_a_border(g: OccupancyGrid, theta, c, cr, target: OccupancyGrid) -> np.ndarray:
    """Cells of ``target`` whose source point in ``g`` lies within 1e-9 cell of a cell border: there the
    nearest cell is a tie that float rounding of the target's own cell centres decides."""
    rows, cols = np.indices(target.shape)
    u = g.world_to_cell(apply_alignment(target.cell_center(rows, cols), -theta, cr, c))
    return (np.abs(u - np.round(u)) < 1e-9).any(axis=-1)


@settings(max_examples=30, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), theta=st.floats(0.0, 360.0), theta2=st.floats(0.0, 360.0),
       special=st.sampled_from((None,) + SPECIAL_ANGLES), round_geometry=st.booleans())
def test_footprint_warp_pasted_on_a_canvas_equals_the_warp_onto_that_canvas(seed, theta, theta2, special,
                                                                           round_geometry):
    """Team merging warps only a map's known cells, once, onto their footprint, and pastes that onto
    every canvas (merge orders share warps); pair checks count only where two footprints overlap.

    This equals warping the whole map onto the canvas, except on cells whose source point lies exactly
    on a cell border (a tie: the footprint's and the canvas's cell centres are different floats); such
    ties only occur with round geometry at right angles, and the test allows them nowhere else."""
    rng = np.random.default_rng(seed)
    angle = theta if special is None else special
    digits = 2 if round_geometry else 9
    ref = random_grid(rng, tuple(rng.integers(5, 200, 2)), 0.05,
                      tuple(np.round(rng.uniform(-5, 1, 2), digits)))
    movs = [random_grid(rng, tuple(rng.integers(5, 200, 2)), 0.05,
                        tuple(np.round(rng.uniform(-5, 1, 2), digits))) for _ in range(2)]
    for g in movs:  # unknown margins, as around a robot's map
        h, w = g.shape
        r0, c0 = rng.integers(0, h // 2 + 1), rng.integers(0, w // 2 + 1)
        g.states[:r0], g.states[:, :c0] = 0, 0
        g.states[rng.integers(r0, h + 1):], g.states[:, rng.integers(c0, w + 1):] = 0, 0
    cr = tuple(np.round(rng.uniform(-2, 2, 2), digits + 1))
    cms = [tuple(np.round(rng.uniform(-2, 2, 2), digits + 1)) for _ in movs]
    placed = [(movs[0], angle, cms[0]), (movs[1], theta2, cms[1])]
    cv = canvas(ref, [(g.known_part(), t, c) for g, t, c in placed], cr)
    via = []
    for g, t, c in placed:
        direct = warp_grid(g, t, c, cr, cv).states
        k = g.known_part()
        v = warp_grid(k, t, c, cr, footprint(ref, k, t, c, cr))
        differ = paste(v, cv).states != direct
        assert not (differ & ~_on_a_border(g, t, c, cr, cv)).any()
        if not round_geometry:
            assert not differ.any()
        via.append(v)
    layers = [paste(ref, cv)] + [paste(v, cv) for v in via]
    grids = [ref, *via]
    for i, j in ((0, 1), (0, 2), (1, 2)):
        whole = verify(layers[i].states, layers[j].states, nu_min=0.5, min_support=10)
        assert verify(*overlap(grids[i], grids[j]), nu_min=0.5, min_support=10) == whole


def test_fast_evidence_is_computed_on_first_access_and_pickles_resolved(team_views):
    """The fast search defers its counts (the free/free count) and its runner-up: a merge cycle only
    reads θ and the score. Both are computed once, on first access, equal the reference's, and a
    pickled alignment carries the values."""
    import pickle

    _, _, maps, _ = team_views
    (ga, ca), (gb, cb) = maps[0], maps[1]
    problem = RotationProblem(ga, gb, ca, cb, 8.0, "similarity")
    fast, ref = fast_search(problem), reference_search(problem)
    assert callable(fast._runner_up) and callable(fast._counts)
    copy = pickle.loads(pickle.dumps(fast))
    assert not callable(fast._runner_up) and not callable(fast._counts)  # resolved by pickling
    assert copy.runner_up == fast.runner_up and copy.counts == fast.counts == ref.counts
    assert copy.theta_deg == fast.theta_deg and copy.score == fast.score == ref.score
    assert_same_answer(fast, ref)
    assert fast.to_dict()["runner_up_deg"] == fast.runner_up_deg


def assert_same_answer(fast, ref):
    assert fast.theta_deg == ref.theta_deg
    assert fast.score == ref.score and fast.counts == ref.counts
    assert fast.method == "fast" and fast.profile.shape == (360,)
    np.testing.assert_array_equal(fast.fine[0], ref.fine[0])
    np.testing.assert_array_equal(fast.fine[1], ref.fine[1])
    fr, rr = fast.runner_up, ref.runner_up
    assert fr == rr or (math.isnan(fr[0]) and math.isnan(rr[0]))
    assert (fast.profile >= ref.profile).all()  # an upper envelope: exact where evaluated


def test_agree_fast_finds_no_difference():
    """The comparison of benchmarks/agree_fast.py on a few problems of every kind and measure."""
    for kind in agree_fast.KINDS:
        for measure in MEASURES:
            for seed in (7, 8):
                r = agree_fast.compare(agree_fast.problem(seed, kind, measure))
                assert not r["diffs"], (kind, measure, seed, r)


def test_agree_fast_finds_no_difference_on_the_large_roi_paths():
    """The same through the code paths of large ROIs (coarse sectors in 2 × 2 blocks, the refinement
    decided by per-angle bounds, moving-occupied counts cell by cell), taken by small problems here."""
    with agree_fast.large_roi_paths():
        for kind in agree_fast.KINDS:
            for measure in MEASURES:
                r = agree_fast.compare(agree_fast.problem(9, kind, measure))
                assert not r["diffs"], (kind, measure, r)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), n=st.integers(1, 120), mres=st.sampled_from([0.05, 0.05, 0.04, 0.1]),
       start=st.floats(0.0, 360.0), round_centers=st.booleans(), scene=st.booleans())
def test_per_angle_bounds_never_below_the_exact_score(seed, n, mres, start, round_centers, scene):
    """ω̃'s per-angle bound (exact agr̃ and reference-occupied dis; the moving-occupied dis replaced by
    the float32 count of cells certainly covering a reference-free point) is never below the exact value,
    at coarse and refinement angles alike."""
    rng = np.random.default_rng(seed)
    if scene:
        ga, ca, gb, cb, roi = random_view_pair(seed)
        p = RotationProblem(ga, gb, ca, cb, roi, "similarity")
    else:
        ref = random_grid(rng, tuple(rng.integers(20, 120, 2)), 0.05, tuple(rng.uniform(-3, 0, 2)))
        mov = random_grid(rng, tuple(rng.integers(20, 120, 2)), mres, tuple(rng.uniform(-3, 0, 2)))
        cr, cm = rng.uniform(-0.5, 2, 2), rng.uniform(-0.5, 2, 2)
        if round_centers:
            cr, cm = np.round(cr, 1), np.round(cm, 1)
        p = RotationProblem(ref, mov, tuple(cr), tuple(cm), n * 0.05, "similarity")
    angles = [float(a) for a in np.concatenate([start + np.arange(-10, 11) * 0.1, np.arange(0, 360, 7.0)])]
    bounds = SparseEvaluator(p).upper_bounds(angles)
    exact = SparseEvaluator(p).scores(angles)
    assert (bounds >= exact).all()


def test_refinement_scores_are_exact_when_read_and_pickle_as_a_tuple():
    """On large-ROI paths the refinement scores not needed for θ are computed when ``fine`` is read:
    exactly the reference's, whether read by index, by unpacking or through pickling."""
    import pickle

    with agree_fast.large_roi_paths():
        for seed in (1, 2):
            p = agree_fast.problem(seed, "views", "similarity")
            ref = reference_search(p)
            a, b, c = fast_search(p), fast_search(p), fast_search(p)
            np.testing.assert_array_equal(a.fine[1], ref.fine[1])
            angles, values = b.fine
            np.testing.assert_array_equal(values, ref.fine[1])
            np.testing.assert_array_equal(angles, ref.fine[0])
            copy = pickle.loads(pickle.dumps(c))
            assert isinstance(copy.fine, tuple)
            np.testing.assert_array_equal(copy.fine[1], ref.fine[1])
            assert (a.theta_deg, a.score) == (ref.theta_deg, ref.score)


def test_compare_reports_a_difference():
    """The comparison can fail: a search answering another angle is reported."""
    p = agree_fast.problem(3, "views", "similarity")
    wrong = fast_search(p)
    import dataclasses

    shifted = dataclasses.replace(wrong, theta_deg=(wrong.theta_deg + 90.0) % 360.0)
    orig = agree_fast.fast_search
    try:
        agree_fast.fast_search = lambda _p: shifted
        assert "theta/score" in agree_fast.compare(p)["diffs"]
    finally:
        agree_fast.fast_search = orig


def _small_problem(data, measure):
    """An arbitrary small problem: random ternary grids (any state mix, any shape), the moving map's cell
    size 0.04–0.1 m, centers anywhere (often on cell corners or centres), ROIs of 1–24 cells."""
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1), label="seed"))
    mix = data.draw(st.sampled_from(["dirichlet", "sparse", "dense", "free"]), label="mix")
    p = {"dirichlet": rng.dirichlet([0.5, 0.5, 0.5]), "sparse": [0.6, 0.38, 0.02], "dense": [0.1, 0.3, 0.6],
         "free": [0.0, 1.0, 0.0]}[mix]
    grids = []
    for res in (0.05, data.draw(st.sampled_from([0.05, 0.04, 0.1]), label="mres")):
        h, w = data.draw(st.integers(1, 30)), data.draw(st.integers(1, 30))
        org = tuple(np.round(rng.uniform(-1, 0, 2), data.draw(st.integers(1, 4))))
        grids.append(OccupancyGrid(rng.choice(3, size=(h, w), p=p).astype(np.uint8), res, org))
    if data.draw(st.booleans(), label="identical"):
        grids[1] = grids[0]
    digits = data.draw(st.integers(1, 6), label="center digits")
    cr = tuple(np.round(rng.uniform(-0.2, 1.2, 2), digits))
    cm = cr if data.draw(st.booleans(), label="same center") else tuple(np.round(rng.uniform(-0.2, 1.2, 2), digits))
    n = data.draw(st.integers(1, 24), label="roi cells")
    return RotationProblem(grids[0], grids[1], cr, cm, n * 0.05, measure)


@settings(max_examples=80, deadline=None, derandomize=True)
@given(data=st.data(), measure=st.sampled_from(MEASURES), large=st.booleans())
def test_fast_equals_reference_on_arbitrary_small_grids(data, measure, large):
    p = _small_problem(data, measure)
    ref = reference_search(p)
    with agree_fast.large_roi_paths() if large else contextlib.nullcontext():
        assert_same_answer(fast_search(p), ref)
        np.testing.assert_array_equal(exact_profile(p), ref.profile)


@settings(max_examples=30, deadline=None, derandomize=True)
@given(data=st.data(), measure=st.sampled_from(MEASURES))
def test_sector_bounds_never_below_the_exact_profile(data, measure):
    """The bound behind every skipped angle: at all 360 coarse angles, never below the exact score —
    with the default sectors and with coarse sectors read in blocks of 2–9 cells (large ROIs' setting)."""
    if data.draw(st.booleans(), label="generated scene"):
        ga, ca, gb, cb, roi = random_view_pair(data.draw(st.integers(0, 10_000), label="seed"))
        p = RotationProblem(ga, gb, ca, cb, roi, measure)
    else:
        p = _small_problem(data, measure)
    grain = data.draw(st.sampled_from([None, 3.0, 6.0, 9.0]), label="sector grain")
    pool_div = data.draw(st.sampled_from([3.0, 2.0, 1.0]), label="pool divisor")
    ev = SparseEvaluator(p)
    saved = fast_mod.sector_grain, fast_mod.POOL_DIV
    try:
        if grain is not None:
            fast_mod.sector_grain, fast_mod.POOL_DIV = (lambda n: grain), pool_div
        fast_mod.clear_cache()
        bounds = SectorBounds(p, ev.ref_roi, int(ev.sx)).values
        assert (bounds >= exact_profile(p)).all()
        assert_same_answer(fast_search(p), reference_search(p))
    finally:
        fast_mod.sector_grain, fast_mod.POOL_DIV = saved
        fast_mod.clear_cache()


@settings(max_examples=25, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), theta=st.floats(0.0, 359.9), roi=st.floats(3.2, 8.0),
       arc_shift=st.floats(-40.0, 40.0), arc=st.floats(5.0, 60.0))
def test_fast_equals_reference_similarity(seed, theta, roi, arc_shift, arc):
    ga, ca, gb, cb = two_views(seed, theta, arc_shift=arc_shift, arc=arc)
    p = RotationProblem(ga, gb, ca, cb, roi, "similarity")
    assert_same_answer(fast_search(p), reference_search(p))


@settings(max_examples=12, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), theta=st.floats(0.0, 359.9), roi=st.floats(3.2, 8.0),
       arc_shift=st.floats(-40.0, 40.0), measure=st.sampled_from(("birk_carpin", "ncc")))
def test_fast_equals_reference_other_measures(seed, theta, roi, arc_shift, measure):
    ga, ca, gb, cb = two_views(seed, theta, arc_shift=arc_shift, arc=30.0)
    p = RotationProblem(ga, gb, ca, cb, roi, measure)
    assert_same_answer(fast_search(p), reference_search(p))


@settings(max_examples=3, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), roi=st.floats(9.6, 12.8), measure=st.sampled_from(MEASURES))
def test_fast_equals_reference_with_a_pooled_polar_stage(seed, roi, measure):
    """ROIs of 192 cells and more are max-pooled 2× before the polar stage: still the reference's answer."""
    ga, ca, gb, cb, _ = random_view_pair(seed, scale=2.0)
    p = RotationProblem(ga, gb, ca, cb, roi, measure)
    assert pool_factor(p.n) >= 2
    assert_same_answer(fast_search(p), reference_search(p))


def test_fast_equals_reference_on_degenerate_problems():
    """Blank maps, tiny ROIs, an ROI off the maps, a map against itself on the cell lattice (every
    lookup on a cell border at 0°/90°): the same answer, through the exact fallbacks where needed."""
    rng = np.random.default_rng(11)
    scene = room_scene(rng)
    g, c = partial_view(scene, (0.0, 0.0, 0.0), arc_viewpoints(30, 40, 1.8, k=3))
    blank = OccupancyGrid.unknown(g.height, g.width, g.resolution, g.origin)
    on_lattice = (round(c[0], 1), round(c[1], 1))
    cases = [(g, blank, c, c, 4.0), (blank, g, c, c, 4.0), (blank, blank, c, c, 2.0),
             (g, g, c, c, 0.05), (g, g, c, c, 0.2), (g, g, (50.0, 50.0), c, 3.0),
             (g, g, on_lattice, on_lattice, 3.0), (g, g, on_lattice, on_lattice, 3.05)]
    for ref, mov, cr, cm, roi in cases:
        for measure in ("similarity", "ncc"):
            p = RotationProblem(ref, mov, cr, cm, roi, measure)
            fast, want = fast_search(p), reference_search(p)
            assert (fast.theta_deg, fast.score, fast.counts) == (want.theta_deg, want.score, want.counts)


def sweep_problem(seed: int, measure: str) -> RotationProblem:
    """A problem of the randomized comparisons (``benchmarks/agree_fast.py``)."""
    ga, ca, gb, cb, roi = random_view_pair(seed)
    return RotationProblem(ga, gb, ca, cb, roi, measure)


def test_fast_equals_reference_on_past_misses():
    """The two sweep cases an earlier version got wrong: a flat Birk–Carpin top whose exact maximum was
    two degrees from the approximate one, and an NCC half-turn peak ranked too low by the approximation."""
    for seed, measure in ((1171, "birk_carpin"), (5158, "ncc")):
        p = sweep_problem(seed, measure)
        assert_same_answer(fast_search(p), reference_search(p))


def test_fast_equals_reference_on_a_symmetric_scene():
    """A point-symmetric room: two peaks 180° apart of nearly equal height, ties broken the same way."""
    rng = np.random.default_rng(5)
    scene = room_scene(rng, n_boxes=0, room_center=(0.0, 0.0))
    ga, ca = partial_view(scene, (0.2, -0.1, 0.3), arc_viewpoints(40, 60, 1.8, k=3))
    gb, cb = partial_view(scene, (-0.3, 0.2, 0.3 + math.radians(123.4)), arc_viewpoints(100, 60, 1.8, k=3))
    for measure in ("similarity", "ncc"):
        p = RotationProblem(ga, gb, ca, cb, 6.0, measure)
        assert_same_answer(fast_search(p), reference_search(p))


@settings(max_examples=3, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), arc=st.floats(15.0, 45.0), roi=st.sampled_from([4.0, 5.0, 6.0]),
       measure=st.sampled_from(("similarity", "ncc")))
def test_team_merge_same_verdict(seed, arc, roi, measure):
    """merge_team with the fast search: same accepted flag, chosen order and angles as the reference."""
    rng = np.random.default_rng(seed)
    scene = room_scene(rng)
    maps = []
    for name, a in zip(("Lyon", "Auckland", "Nevers"), (90.0, 210.0, 330.0), strict=True):
        pose = robot_pose_on_circle(a, 1.8, yaw_offset_deg=rng.uniform(-40, 40))
        g, c = partial_view(scene, pose, arc_viewpoints(a, arc, 1.8), noise=0.002, rng=rng)
        maps.append(MapInput(name, g, c))
    verification = "whole_map" if measure == "similarity" else "roi_score"
    results = [merge_team(maps, MergeParams(roi_m=roi, measure=measure, method=m, verification=verification,
                                                window_m=0.0, refine=False))
               for m in ("fast", "reference")]
    fast, ref = results
    assert fast.accepted == ref.accepted
    assert [o.accepted for o in fast.orders] == [o.accepted for o in ref.orders]
    assert fast.top.order == ref.top.order
    for of, orf in zip(fast.orders, ref.orders, strict=True):
        for name in of.theta_deg:
            assert abs(angle_diff_deg(of.theta_deg[name], orf.theta_deg[name])) <= 0.1 + 1e-9
        assert of.nu == orf.nu
    if ref.accepted:
        np.testing.assert_array_equal(fast.merged.states, ref.merged.states)
