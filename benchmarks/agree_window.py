"""Correctness of the rotation × translation search: fast vs the exhaustive reference, and both vs truth.

Run from the repository root::

    python benchmarks/agree_window.py                  # 20 problems per kind (a few minutes)
    python benchmarks/agree_window.py --n 50 --kinds views,sparse
    python benchmarks/agree_window.py --accuracy-n 40  # also: ROI 8 m, W 0.5 m, fast only, vs truth

Problems are :func:`merger.synthetic.window_case`: a generated room seen in two frames (``views``), a
point-symmetric room seen over a short arc (``symmetric``), pillars and boxes without walls in range
(``sparse``), a view against itself (``identical``, plateaus) and random ternary grids (``noise``), each
with the moving center off by up to 0.8 × the window on each axis; ROI 3.2–4.8 m and window 0.15–0.4 m
so that the exhaustive reference ((2K+1)² translations × 360 angles, then 21 fine angles) stays cheap.
"same": the fast method's grid answer (θ, t) and score equal the reference's (refinement off). The
fast method is not exact by construction (its candidates come from an approximate polar stage); this
script counts where it differs and how far its score is below the reference's.

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

from merger.search import RotationProblem, angle_diff_deg, search  # noqa: E402
from merger.synthetic import WINDOW_KINDS, window_case  # noqa: E402


def compare(seed: int, kind: str, measure: str) -> dict:
    c = window_case(seed, kind)
    p = RotationProblem(c.ref, c.moving, c.center_ref, c.center_moving, c.roi_m, measure,
                        min(c.window_m, c.roi_m / 4))
    t0 = time.perf_counter()
    ref = search(p, "reference")
    t1 = time.perf_counter()
    fast = search(p, "fast")
    t2 = time.perf_counter()
    same = (fast.theta_deg, fast.translation_m, fast.score) == (ref.theta_deg, ref.translation_m, ref.score)
    return {"seed": seed, "kind": kind, "same": same, "gap": ref.score - fast.score,
            "ref_ms": (t1 - t0) * 1e3, "fast_ms": (t2 - t1) * 1e3,
            "ref": (ref.theta_deg, ref.translation_m, round(ref.score, 4)),
            "fast": (fast.theta_deg, fast.translation_m, round(fast.score, 4))}


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
    ap.add_argument("--n", type=int, default=20, help="problems per kind (default 20)")
    ap.add_argument("--kinds", default=",".join(WINDOW_KINDS))
    ap.add_argument("--measure", default="similarity", choices=("similarity", "birk_carpin", "ncc"))
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--accuracy-n", type=int, default=0, help="problems per kind at ROI 8 m / W 0.5 m vs truth")
    args = ap.parse_args(argv)
    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    if any(k not in WINDOW_KINDS for k in kinds) or args.n < 0:
        ap.error(f"--kinds must be among {', '.join(WINDOW_KINDS)} and --n ≥ 0")
    total = same_total = 0
    if args.n:
        print(f"fast vs reference, measure {args.measure}, refinement off (grid answers)")
        print(f"{'kind':>10} {'problems':>8} {'same':>5} {'max score gap':>14} {'ref ms':>8} {'fast ms':>8}")
        for k in kinds:
            rows = [compare(s, k, args.measure) for s in range(args.first_seed, args.first_seed + args.n)]
            total += len(rows)
            same_total += sum(r["same"] for r in rows)
            print(f"{k:>10} {len(rows):>8} {sum(r['same'] for r in rows):>5} "
                  f"{max(r['gap'] for r in rows):>14.4f} {statistics.median(r['ref_ms'] for r in rows):>8.0f} "
                  f"{statistics.median(r['fast_ms'] for r in rows):>8.1f}")
            for r in rows:
                if not r["same"]:
                    print(f"    differs: {k} seed {r['seed']}: fast {r['fast']} vs reference {r['ref']}")
        print(f"same answer on {same_total}/{total}")
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
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
