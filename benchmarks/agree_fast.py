"""Correctness at scale: the fast rotation search against the reference on many generated problems.

Run from the repository root::

    python benchmarks/agree_fast.py                       # 120 problems per kind and measure (~3000)
    python benchmarks/agree_fast.py --n 10                # quicker
    python benchmarks/agree_fast.py --kinds noise,identical --measures ncc --first-seed 1000
    python benchmarks/agree_fast.py --kinds views --scale 2 --n 50   # ROIs of 128–320 cells

Problem kinds (:func:`problem`), each for the three measures (ω̃, Birk–Carpin ω, NCC):

* ``views`` — :func:`merger.synthetic.random_view_pair`: two partial views of a generated room,
  rotated by a random θ, varying overlap, ROI 3.2–8 m (× ``--scale``);
* ``rough`` — :func:`merger.synthetic.window_case` ``views``: the same with the moving center off by up
  to ±0.32 m per axis (imprecise centers; searched rotation-only, as the thesis does);
* ``symmetric`` — a point-symmetric room with two pillars seen over short arcs (3–12°), rough centers:
  the thesis's 180° ambiguity;
* ``sparse`` — pillars and boxes, no walls in range (the chair-legs case), rough centers;
* ``noise`` — random ternary grids (random state mix), rough centers;
* ``identical`` — a view against itself (θ = 0 plateau), rough centers;
* ``lattice`` — a view against itself (or a random grid against itself) with both centers on cell
  corners or centres: every lookup at 0°, 90°, 180°, 270° lies on a cell border (the exact fallbacks),
  and whole plateaus of equal scores;
* ``near_empty`` — nearly blank maps: a handful (0–6) of occupied cells, some free space, or none;
* ``mixed`` — random grids whose moving map has another cell size (0.04, 0.1 m) and tiny ROIs (1–40 cells).

``--paths large`` runs every problem through the code paths of large ROIs (from ROI side
``merger.fast.LARGE_ROI`` on): 10-cell sectors read in blocks of 2 × 2 cells, the refinement decided by
per-angle bounds (exact scores only where a bound reaches the best), and the moving-occupied counts cell
by cell (:func:`large_roi_paths`); the default runs each problem through the paths of its own size.

For each problem both searches run and the script checks that the fast answer *is* the reference's:
θ, score, counts, the 21 refinement scores, the runner-up (angle and score), and that the fast
profile is an upper envelope of the reference's (≥ at every angle). It prints a table per kind and
measure and lists every difference (kind, seed, measure, both answers); exit code 1 if there is any.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import contextlib  # noqa: E402

import numpy as np  # noqa: E402

import merger.fast as fast_mod  # noqa: E402
import merger.sparse as sparse_mod  # noqa: E402
from merger.fast import fast_search  # noqa: E402
from merger.grid import OccupancyGrid  # noqa: E402
from merger.search import RotationProblem, reference_search  # noqa: E402
from merger.synthetic import near_empty_grid, random_view_pair, window_case  # noqa: E402

MEASURES = ("similarity", "birk_carpin", "ncc")
KINDS = ("views", "rough", "symmetric", "sparse", "noise", "identical", "lattice", "near_empty", "mixed")


def _random_states(rng, shape, p=None) -> np.ndarray:
    p = rng.dirichlet([1, 1, 1]) if p is None else p
    return rng.choice(3, size=shape, p=p).astype(np.uint8)


def problem(seed: int, kind: str, measure: str, scale: float = 1.0) -> RotationProblem:
    """The rotation problem ``seed`` of ``kind`` (see the module documentation) for ``measure``."""
    if kind == "views":
        ga, ca, gb, cb, roi = random_view_pair(seed, scale)
        return RotationProblem(ga, gb, ca, cb, roi, measure)
    if kind in ("rough", "symmetric", "sparse", "noise", "identical"):
        c = window_case(seed, "views" if kind == "rough" else kind)
        return RotationProblem(c.ref, c.moving, c.center_ref, c.center_moving, c.roi_m, measure)
    rng = np.random.default_rng([seed, KINDS.index(kind)])
    if kind == "lattice":
        if rng.random() < 0.5:
            c = window_case(seed, "identical")
            g = c.ref
        else:
            side = int(rng.integers(20, 90))
            g = OccupancyGrid(_random_states(rng, (side, side)), 0.05, (-side * 0.025, -side * 0.025))
        step = 0.05 if rng.random() < 0.5 else 0.025  # cell corners, or corners and centres
        x0, x1, y0, y1 = g.extent
        cx = round(float(rng.uniform(x0 + 0.2 * (x1 - x0), x1 - 0.2 * (x1 - x0))) / step) * step
        cy = round(float(rng.uniform(y0 + 0.2 * (y1 - y0), y1 - 0.2 * (y1 - y0))) / step) * step
        roi = int(rng.integers(1, 80)) * 0.05
        return RotationProblem(g, g, (cx, cy), (cx, cy), roi, measure)
    if kind == "near_empty":
        grids = [near_empty_grid(rng) for _ in range(2)]
        c = [tuple(rng.uniform(-0.3, 0.3, 2)) for _ in range(2)]
        return RotationProblem(grids[0], grids[1], c[0], c[1], float(rng.uniform(0.5, 4.0)), measure)
    if kind == "mixed":
        ref_side, mov_res = int(rng.integers(20, 100)), float(rng.choice([0.04, 0.1, 0.05]))
        mov_side = int(rng.integers(10, 100))
        ref = OccupancyGrid(_random_states(rng, (ref_side, ref_side)), 0.05, tuple(rng.uniform(-3, -1, 2)))
        mov = OccupancyGrid(_random_states(rng, (mov_side, mov_side)), mov_res, tuple(rng.uniform(-3, -1, 2)))
        c = [tuple(rng.uniform(-1, 1, 2)) for _ in range(2)]
        return RotationProblem(ref, mov, c[0], c[1], int(rng.integers(1, 41)) * 0.05, measure)
    raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")


@contextlib.contextmanager
def large_roi_paths():
    """Within the block, every ROI takes the code paths of large ROIs (the size thresholds set to 0)."""
    saved = fast_mod.LARGE_ROI, fast_mod.FINE_EXACT_MAX, sparse_mod.UNION_MAX_CELLS
    fast_mod.LARGE_ROI = fast_mod.FINE_EXACT_MAX = sparse_mod.UNION_MAX_CELLS = 0
    fast_mod.clear_cache()
    try:
        yield
    finally:
        fast_mod.LARGE_ROI, fast_mod.FINE_EXACT_MAX, sparse_mod.UNION_MAX_CELLS = saved
        fast_mod.clear_cache()


def compare(p: RotationProblem) -> dict:
    """Both searches on ``p``: does the fast one give the reference's answer, evidence included?"""
    t0 = time.perf_counter()
    ref = reference_search(p)
    t1 = time.perf_counter()
    fast = fast_search(p)
    t2 = time.perf_counter()
    diffs = []
    if (fast.theta_deg, fast.score) != (ref.theta_deg, ref.score):
        diffs.append("theta/score")
    if fast.counts != ref.counts:
        diffs.append("counts")
    if not (np.array_equal(fast.fine[0], ref.fine[0]) and np.array_equal(fast.fine[1], ref.fine[1])):
        diffs.append("fine")
    fr, rr = fast.runner_up, ref.runner_up
    if not (fr == rr or (all(math.isnan(v) for v in fr) and all(math.isnan(v) for v in rr))):
        diffs.append("runner-up")
    if not (fast.profile >= ref.profile).all():
        diffs.append("profile not an upper envelope")
    return {"diffs": diffs, "ref_ms": (t1 - t0) * 1e3, "fast_ms": (t2 - t1) * 1e3,
            "fast": (fast.theta_deg, fast.score, fr), "ref": (ref.theta_deg, ref.score, rr)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=120, help="problems per kind and measure (default 120)")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--scale", type=float, default=1.0, help="scale of the 'views' kind (default 1)")
    ap.add_argument("--kinds", default=",".join(KINDS), help="comma-separated subset of " + ", ".join(KINDS))
    ap.add_argument("--measures", default=",".join(MEASURES), help="comma-separated subset of " + ", ".join(MEASURES))
    ap.add_argument("--paths", choices=("default", "large"), default="default",
                    help="'large': every problem through the large-ROI code paths (default: its own size's)")
    args = ap.parse_args(argv)
    measures = [m.strip() for m in args.measures.split(",") if m.strip()]
    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    bad = [m for m in measures if m not in MEASURES] + [k for k in kinds if k not in KINDS]
    if bad or args.n < 1 or not args.scale > 0:
        ap.error(f"--measures among {', '.join(MEASURES)}, --kinds among {', '.join(KINDS)}, --n ≥ 1, --scale > 0")
    with large_roi_paths() if args.paths == "large" else contextlib.nullcontext():
        return _run(args, kinds, measures)


def _run(args, kinds: list[str], measures: list[str]) -> int:
    print(f"{'kind':>10} {'measure':>12} {'problems':>8} {'same':>6} {'ref ms':>8} {'fast ms':>8}   (medians)",
          flush=True)
    failures, total, same = [], 0, 0
    for kind in kinds:
        for m in measures:
            rows = []
            for s in range(args.first_seed, args.first_seed + args.n):
                r = compare(problem(s, kind, m, args.scale))
                r.update(seed=s, kind=kind, measure=m)
                rows.append(r)
            failures += [r for r in rows if r["diffs"]]
            ok = sum(not r["diffs"] for r in rows)
            total, same = total + len(rows), same + ok
            print(f"{kind:>10} {m:>12} {len(rows):>8} {ok:>6} {statistics.median(r['ref_ms'] for r in rows):>8.0f} "
                  f"{statistics.median(r['fast_ms'] for r in rows):>8.1f}", flush=True)
    print(f"total: {same} of {total} problems give the reference's answer; {total - same} differ"
          f"{' (large-ROI code paths)' if args.paths == 'large' else ''}")
    for r in failures:
        print(f"DIFF {r['kind']} seed {r['seed']} {r['measure']}: {', '.join(r['diffs'])}; fast θ, score, runner-up "
              f"{r['fast']} vs reference {r['ref']}")
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
