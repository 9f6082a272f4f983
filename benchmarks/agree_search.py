"""Exactness at scale: ``fast`` against the compiled exhaustive reference on many adversarial problems.

    python benchmarks/agree_search.py [--n 1000] [--full 20]
    python benchmarks/agree_search.py --local [--n 1000]   # the local search against the exhaustive one

``--n`` problems per measure (similarity, birk_carpin, ncc) from ``tests/strategies.adversarial_problem``
(random ternary grids, a map against its rotated copy shifted by one cell, walls on the window's edge,
near-empty maps, two resolutions; centers anywhere, on cell centres or corners; rotation only and
windowed), plus ``--full`` full-size problems per measure (generated rooms, ROI 6–8 m, W 0.5 m, centers
on cell centres, corners or anywhere). Prints the number of differences in (θ, t, score, counts) and
the time of each method.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from merger.search import RotationProblem, fast_search, reference_search  # noqa: E402
from merger.search.local import local_search, reference_local  # noqa: E402
from merger.synthetic import WINDOW_KINDS, window_case  # noqa: E402
from tests.strategies import adversarial_problem  # noqa: E402

MEASURES = ("similarity", "birk_carpin", "ncc")


def key(al):
    return (al.theta_deg, al.cells, al.score, al.counts.agree, al.counts.disagree)


def full_size(seed: int, measure: str) -> RotationProblem:
    kind = WINDOW_KINDS[seed % len(WINDOW_KINDS)]
    c = window_case(seed, kind, roi_m=(6.0, 8.0), window_m=(0.5, 0.5), error_frac=0.5)
    cr = np.array(c.center_ref)
    g = c.ref
    mode = seed % 3
    if mode:
        cr = np.array(g.origin) + (np.floor((cr - g.origin) / g.resolution) + (0.5 if mode == 1 else 0.0)) * g.resolution
    return RotationProblem(g, c.moving, tuple(cr), c.center_moving, c.roi_m, measure, 0.5)


def local_main(args) -> int:
    """The local search (merger.search.local) against the exhaustive search restricted to its region, on
    ``--n`` adversarial problems per measure, each about a region centred at a random angle and cell of
    the window (seeded: the same problems every run)."""
    total = diff = 0
    t_ref = t_fast = 0.0
    for measure in args.measures.split(","):
        d = 0
        for s in range(args.start, args.start + args.n):
            p = adversarial_problem(s, measure, s % 2 == 1)
            rng = np.random.default_rng(s)
            k = p.window_cells
            theta = float(rng.choice([rng.uniform(0, 360), round(rng.uniform(0, 360)), 0.0, 359.6]))
            cells = (int(rng.integers(-k, k + 1)), int(rng.integers(-k, k + 1)))
            t0 = time.perf_counter()
            r = reference_local(p, theta, cells)
            t1 = time.perf_counter()
            f = local_search(p, theta, cells)
            t2 = time.perf_counter()
            t_ref += t1 - t0
            t_fast += t2 - t1
            if key(r) != key(f):
                d += 1
                print(f"  DIFFERENCE {measure} small {s}: reference_local {key(r)} local {key(f)}", flush=True)
        total += args.n
        diff += d
        print(f"{measure}: {d} differences in {args.n} local problems", flush=True)
    print(f"all: {diff} differences in {total} local problems; exhaustive {t_ref:.1f} s, local search {t_fast:.1f} s")
    return 1 if diff else 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--local", action="store_true", help="the local search against the restricted exhaustive one")
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--full", type=int, default=20)
    ap.add_argument("--start", type=int, default=0, help="first seed of the small problems")
    ap.add_argument("--measures", default=",".join(MEASURES), help="comma-separated (default: all three)")
    args = ap.parse_args(argv)
    if args.local:
        return local_main(args)
    total = diff = 0
    t_ref = t_fast = 0.0
    for measure in args.measures.split(","):
        problems = [(f"small {s}", lambda s=s, m=measure: adversarial_problem(s, m, s % 2 == 1)) for s in range(args.start, args.start + args.n)]
        problems += [(f"full {s}", lambda s=s, m=measure: full_size(s, m)) for s in range(args.full)]
        d = 0
        for name, make in problems:
            t0 = time.perf_counter()
            r = reference_search(make())
            t1 = time.perf_counter()
            f = fast_search(make())
            t2 = time.perf_counter()
            t_ref += t1 - t0
            t_fast += t2 - t1
            if key(r) != key(f):
                d += 1
                print(f"  DIFFERENCE {measure} {name}: reference {key(r)} fast {key(f)}", flush=True)
        total += len(problems)
        diff += d
        print(f"{measure}: {d} differences in {len(problems)} problems", flush=True)
    print(f"all: {diff} differences in {total} problems; reference {t_ref:.1f} s, fast {t_fast:.1f} s")
    return 1 if diff else 0


if __name__ == "__main__":
    sys.exit(main())
