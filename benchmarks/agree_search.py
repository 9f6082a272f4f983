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


def compare(cases: dict, names: tuple[str, str], what: str = "problems") -> int:
    """Per measure, every case (name, exhaustive thunk, fast thunk): time both, count the differences in
    (θ, t, score, counts) and print them; returns 1 when any differs."""
    total = diff = 0
    t_ref = t_fast = 0.0
    for measure, items in cases.items():
        d = 0
        for name, ref_fn, fast_fn in items:
            t0 = time.perf_counter()
            r = ref_fn()
            t1 = time.perf_counter()
            f = fast_fn()
            t2 = time.perf_counter()
            t_ref += t1 - t0
            t_fast += t2 - t1
            if key(r) != key(f):
                d += 1
                print(f"  DIFFERENCE {measure} {name}: {names[0]} {key(r)} {names[1]} {key(f)}", flush=True)
        total += len(items)
        diff += d
        print(f"{measure}: {d} differences in {len(items)} {what}", flush=True)
    print(f"all: {diff} differences in {total} {what}; {names[0]} {t_ref:.1f} s, {names[1]} {t_fast:.1f} s")
    return 1 if diff else 0


def local_case(s: int, measure: str):
    """A small adversarial problem and a region about a random angle and cell of its window (seeded)."""
    p = adversarial_problem(s, measure, s % 2 == 1)
    rng = np.random.default_rng(s)
    k = p.window_cells
    theta = float(rng.choice([rng.uniform(0, 360), round(rng.uniform(0, 360)), 0.0, 359.6]))
    cells = (int(rng.integers(-k, k + 1)), int(rng.integers(-k, k + 1)))
    return (f"small {s}", lambda: reference_local(p, theta, cells), lambda: local_search(p, theta, cells))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--local", action="store_true", help="the local search against the restricted exhaustive one")
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--full", type=int, default=20)
    ap.add_argument("--start", type=int, default=0, help="first seed of the small problems")
    ap.add_argument("--measures", default=",".join(MEASURES), help="comma-separated (default: all three)")
    args = ap.parse_args(argv)
    seeds = range(args.start, args.start + args.n)
    measures = args.measures.split(",")
    if args.local:  # the local search (merger.search.local) against the exhaustive search on its region
        return compare({m: [local_case(s, m) for s in seeds] for m in measures}, ("exhaustive", "local"),
                       "local problems")
    cases = {}
    for m in measures:
        makes = [(f"small {s}", lambda s=s, m=m: adversarial_problem(s, m, s % 2 == 1)) for s in seeds]
        makes += [(f"full {s}", lambda s=s, m=m: full_size(s, m)) for s in range(args.full)]
        cases[m] = [(name, lambda mk=mk: reference_search(mk()), lambda mk=mk: fast_search(mk())) for name, mk in makes]
    return compare(cases, ("reference", "fast"))


if __name__ == "__main__":
    sys.exit(main())
