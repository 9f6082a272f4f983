"""Correctness at scale: the fast rotation search against the reference on many generated problems.

Run from the repository root::

    python benchmarks/agree_fast.py                 # 100 problems per measure (a few minutes)
    python benchmarks/agree_fast.py --n 20          # quicker
    python benchmarks/agree_fast.py --measures similarity --first-seed 1000
    python benchmarks/agree_fast.py --scale 2 --n 50   # rooms, circles and ROIs (6.4–16 m) twice as large

Every problem is :func:`merger.synthetic.random_view_pair` (two partial views of a generated room,
rotated by a random θ, with varying overlap and ROI 3.2–8 m, times ``--scale``: at 2, ROIs of 128–320
cells, which the fast search max-pools 1–3× before its polar stage). For each one the script runs both searches
and checks what the tests check on a few cases: the same θ, score and counts (the fast search's answer
is the reference's), and a runner-up at least 10° from θ and never above the reference's. It prints the
number of problems where each holds and lists any that fails (seed, measure, both answers); exit code 1
if the fast search ever gives a different answer or a runner-up that breaks those rules.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from merger.fast import fast_search  # noqa: E402
from merger.search import RotationProblem, angle_diff_deg, reference_search  # noqa: E402
from merger.synthetic import random_view_pair  # noqa: E402

MEASURES = ("similarity", "birk_carpin", "ncc")


def compare(seed: int, measure: str, scale: float = 1.0) -> dict:
    ga, ca, gb, cb, roi = random_view_pair(seed, scale)
    p = RotationProblem(ga, gb, ca, cb, roi, measure)
    t0 = time.perf_counter()
    ref = reference_search(p)
    t1 = time.perf_counter()
    fast = fast_search(p)
    t2 = time.perf_counter()
    same = (fast.theta_deg, fast.score, fast.counts) == (ref.theta_deg, ref.score, ref.counts)
    ru_far = abs(angle_diff_deg(fast.runner_up_deg, fast.theta_deg)) >= 10.0
    return {"seed": seed, "measure": measure, "same": same, "ru_ok": ru_far and fast.runner_up_score <= ref.runner_up_score,
            "ru_equal": fast.runner_up_score == ref.runner_up_score, "ref_ms": (t1 - t0) * 1e3,
            "fast_ms": (t2 - t1) * 1e3, "fast": (fast.theta_deg, fast.score), "ref": (ref.theta_deg, ref.score)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100, help="problems per measure (default 100)")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--scale", type=float, default=1.0, help="scale of rooms, circles and ROIs (default 1)")
    ap.add_argument("--measures", default=",".join(MEASURES), help="comma-separated subset of " + ", ".join(MEASURES))
    args = ap.parse_args(argv)
    measures = [m.strip() for m in args.measures.split(",") if m.strip()]
    bad = [m for m in measures if m not in MEASURES]
    if bad or args.n < 1 or not args.scale > 0:
        ap.error(f"--measures must be among {', '.join(MEASURES)}, --n ≥ 1 and --scale > 0")
    print(f"{'measure':>12} {'problems':>8} {'same answer':>11} {'runner-up ok':>12} {'runner-up =':>11} "
          f"{'ref ms':>8} {'fast ms':>8}   (medians)")
    failures = []
    for m in measures:
        rows = [compare(s, m, args.scale) for s in range(args.first_seed, args.first_seed + args.n)]
        failures += [r for r in rows if not (r["same"] and r["ru_ok"])]
        print(f"{m:>12} {len(rows):>8} {sum(r['same'] for r in rows):>11} {sum(r['ru_ok'] for r in rows):>12} "
              f"{sum(r['ru_equal'] for r in rows):>11} {statistics.median(r['ref_ms'] for r in rows):>8.0f} "
              f"{statistics.median(r['fast_ms'] for r in rows):>8.1f}")
    for r in failures:
        print(f"FAIL seed {r['seed']} {r['measure']}: fast θ, score {r['fast']} vs reference {r['ref']}; "
              f"same answer {r['same']}, runner-up ok {r['ru_ok']}")
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
