"""Correctness of the rotation × translation search: fast vs the exhaustive reference, and both vs truth.

Run from the repository root::

    python benchmarks/agree_window.py                  # 20 problems per kind and measure
    python benchmarks/agree_window.py --n 50 --kinds views,sparse --measures similarity
    python benchmarks/agree_window.py --small --n 100  # ROI 1.2–2.4 m, window 0.1–0.3 m: a cheap reference
    python benchmarks/agree_window.py --accuracy-n 40  # also: ROI 8 m, W 0.5 m, fast only, vs truth

Problem kinds: :func:`merger.synthetic.window_case` — a generated room seen in two frames (``views``), a
point-symmetric room seen over a short arc (``symmetric``), pillars and boxes without walls in range
(``sparse``), a view against itself (``identical``, plateaus) and random ternary grids (``noise``), each
with the moving center off by up to 0.8 × the window on each axis; and two generated here:
``near_empty`` (nearly blank maps: a handful of occupied cells, some free space or none) and
``lattice`` (a map, or a random grid, against itself with both centers on cell corners or centres:
lookups on cell borders, reference ROIs that are not plain blocks, whole plateaus of equal scores).
ROI 3.2–4.8 m and window 0.15–0.4 m by default (``--small``: ROI 1.2–2.4 m, window 0.1–0.3 m), so that the
exhaustive reference ((2K+1)² translations × 360 angles, then 21 fine angles) stays affordable.

"same": the fast method's grid answer (θ, t), score and counts equal the reference's (refinement off),
its profile is an upper envelope of the reference's, and :func:`merger.window.exact_window_runner_up`
equals the reference's runner-up (the fast search's own ``runner_up`` is the approximate one;
``--no-runner-up`` skips this check). The fast method is exact by construction (:mod:`merger.window`);
this script checks it. Exit code 1 on any difference.

``--accuracy-n`` adds the issue's operating point (ROI 8 m, window 0.5 m, errors up to 0.4 m), fast with
refinement, against ground truth: θ and t errors (problems whose best ROI score is the 180° alignment
of a symmetric scene are counted apart: whole-map verification is what rejects those).
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from merger.grid import OccupancyGrid  # noqa: E402
from merger.search import RotationProblem, angle_diff_deg, search  # noqa: E402
from merger.synthetic import WINDOW_KINDS, near_empty_grid, window_case  # noqa: E402
from merger.window import exact_window_runner_up  # noqa: E402

MEASURES = ("similarity", "birk_carpin", "ncc")
KINDS = (*WINDOW_KINDS, "near_empty", "lattice")
SIZES = {"default": ((3.2, 4.8), (0.15, 0.4)), "small": ((1.2, 2.4), (0.1, 0.3))}


def problem(seed: int, kind: str, measure: str, size: str = "default") -> RotationProblem:
    """The windowed problem ``seed`` of ``kind`` (see the module documentation) for ``measure``."""
    roi_r, win_r = SIZES[size]
    if kind in WINDOW_KINDS:
        c = window_case(seed, kind, roi_m=roi_r, window_m=win_r)
        return RotationProblem(c.ref, c.moving, c.center_ref, c.center_moving, c.roi_m, measure,
                               min(c.window_m, c.roi_m / 4))
    rng = np.random.default_rng([seed, KINDS.index(kind), 11])
    roi = float(rng.uniform(*roi_r))
    win = min(float(rng.uniform(*win_r)), roi / 4)
    if kind == "near_empty":
        grids = [near_empty_grid(rng) for _ in range(2)]
        c = [tuple(float(v) for v in rng.uniform(-0.3, 0.3, 2)) for _ in range(2)]
        return RotationProblem(grids[0], grids[1], c[0], c[1], roi, measure, win)
    if kind == "lattice":
        if rng.random() < 0.5:
            g = window_case(seed, "identical", roi_m=roi_r, window_m=win_r).ref
        else:
            side = int(rng.integers(20, 90))
            g = OccupancyGrid(rng.choice(3, size=(side, side), p=rng.dirichlet([1, 1, 1])).astype(np.uint8),
                              0.05, (-side * 0.025, -side * 0.025))
        step = 0.05 if rng.random() < 0.5 else 0.025  # cell corners, or corners and centres
        x0, x1, y0, y1 = g.extent
        cx = round(float(rng.uniform(x0 + 0.2 * (x1 - x0), x1 - 0.2 * (x1 - x0))) / step) * step
        cy = round(float(rng.uniform(y0 + 0.2 * (y1 - y0), y1 - 0.2 * (y1 - y0))) / step) * step
        return RotationProblem(g, g, (cx, cy), (cx, cy), roi, measure, win)
    raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")


def compare(seed: int, kind: str, measure: str, size: str = "default", runner_up: bool = True) -> dict:
    """Both searches (refinement off) on problem ``seed`` of ``kind``: the differences found, if any."""
    p = problem(seed, kind, measure, size)
    t0 = time.perf_counter()
    ref = search(p, "reference")
    t1 = time.perf_counter()
    fast = search(p, "fast")
    t2 = time.perf_counter()
    diffs = []
    if (fast.theta_deg, fast.translation_m, fast.cells, fast.score) != \
            (ref.theta_deg, ref.translation_m, ref.cells, ref.score):
        diffs.append("answer")
    if fast.counts != ref.counts:
        diffs.append("counts")
    if not (fast.profile >= ref.profile).all():
        diffs.append("profile not an upper envelope")
    rr = ref.runner_up
    fr = exact_window_runner_up(p, fast.theta_deg) if runner_up else rr
    if not (fr == rr or (all(math.isnan(v) for v in fr) and all(math.isnan(v) for v in rr))):
        diffs.append("runner-up")
    return {"seed": seed, "kind": kind, "measure": measure, "diffs": diffs, "gap": ref.score - fast.score,
            "ref_ms": (t1 - t0) * 1e3, "fast_ms": (t2 - t1) * 1e3,
            "ref": (ref.theta_deg, ref.translation_m, round(ref.score, 4), rr),
            "fast": (fast.theta_deg, fast.translation_m, round(fast.score, 4), fr)}


def accuracy(seed: int, kind: str) -> dict:
    c = window_case(seed, kind, roi_m=(8.0, 8.0), window_m=(0.5, 0.5))
    p = RotationProblem(c.ref, c.moving, c.center_ref, c.center_moving, 8.0, "similarity", 0.5, True)
    t0 = time.perf_counter()
    al = search(p, "fast")
    ms = (time.perf_counter() - t0) * 1e3
    e_th = abs(angle_diff_deg(al.theta_deg, c.theta_deg))
    return {"kind": kind, "seed": seed, "flip": e_th > 90, "theta": e_th,
            "t": math.dist(al.translation_m, c.translation_m), "ms": ms,
            "grid_theta": abs(angle_diff_deg(al.theta_grid_deg, c.theta_deg)),
            "grid_t": math.dist(al.translation_grid_m, c.translation_m)}


def q(values, p):
    return float(np.percentile(values, p)) if values else float("nan")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=20, help="problems per kind and measure (default 20)")
    ap.add_argument("--kinds", default=",".join(KINDS))
    ap.add_argument("--measures", default=",".join(MEASURES), help="comma-separated subset of " + ", ".join(MEASURES))
    ap.add_argument("--small", action="store_true", help="ROI 1.2–2.4 m, window 0.1–0.3 m (a cheaper reference)")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--no-runner-up", action="store_true", help="skip the exact runner-up's check")
    ap.add_argument("--accuracy-n", type=int, default=0, help="problems per kind at ROI 8 m / W 0.5 m vs truth")
    args = ap.parse_args(argv)
    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    measures = [m.strip() for m in args.measures.split(",") if m.strip()]
    if any(k not in KINDS for k in kinds) or any(m not in MEASURES for m in measures) or args.n < 0:
        ap.error(f"--kinds among {', '.join(KINDS)}, --measures among {', '.join(MEASURES)}, --n ≥ 0")
    size = "small" if args.small else "default"
    failures, total = [], 0
    if args.n:
        print(f"fast vs reference, refinement off (grid answers), sizes: {size}", flush=True)
        print(f"{'kind':>10} {'measure':>12} {'problems':>8} {'same':>5} {'max score gap':>14} {'ref ms':>8} "
              f"{'fast ms':>8}   (medians)", flush=True)
        for k in kinds:
            for m in measures:
                rows = [compare(s, k, m, size, not args.no_runner_up) for s in range(args.first_seed, args.first_seed + args.n)]
                total += len(rows)
                failures += [r for r in rows if r["diffs"]]
                print(f"{k:>10} {m:>12} {len(rows):>8} {sum(not r['diffs'] for r in rows):>5} "
                      f"{max(r['gap'] for r in rows):>14.4f} {statistics.median(r['ref_ms'] for r in rows):>8.0f} "
                      f"{statistics.median(r['fast_ms'] for r in rows):>8.1f}", flush=True)
        print(f"total: {total - len(failures)} of {total} problems give the reference's answer; "
              f"{len(failures)} differ")
        for r in failures:
            print(f"DIFF {r['kind']} seed {r['seed']} {r['measure']}: {', '.join(r['diffs'])}; fast (θ, t, score, "
                  f"runner-up) {r['fast']} vs reference {r['ref']}")
    if args.accuracy_n:
        print()
        print("fast with refinement vs truth: ROI 8 m, window 0.5 m, moving center off by up to 0.4 m/axis")
        print(f"{'kind':>10} {'n':>4} {'180° best':>9} {'θ err p50/p90/max °':>22} {'t err p50/p90/max cm':>22} "
              f"{'grid θ max':>10} {'grid t max':>10} {'fast ms':>8}")
        for k in [k for k in kinds if k in ("views", "sparse", "symmetric", "identical")]:
            rows = [accuracy(s, k) for s in range(args.accuracy_n)]
            ok = [r for r in rows if not r["flip"]]
            th, tt = [r["theta"] for r in ok], [r["t"] * 100 for r in ok]
            print(f"{k:>10} {len(rows):>4} {len(rows) - len(ok):>9} "
                  f"{q(th, 50):>8.2f}/{q(th, 90):.2f}/{max(th, default=float('nan')):.2f} "
                  f"{q(tt, 50):>10.1f}/{q(tt, 90):.1f}/{max(tt, default=float('nan')):.1f} "
                  f"{max((r['grid_theta'] for r in ok), default=float('nan')):>10.2f} "
                  f"{max((r['grid_t'] for r in ok), default=float('nan')) * 100:>9.1f}c "
                  f"{statistics.median(r['ms'] for r in rows):>8.1f}")
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
