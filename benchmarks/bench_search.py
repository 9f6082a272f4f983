"""Search speed: the fast branch and bound against the strongest baselines a user would write, same run.

    python benchmarks/bench_search.py [--reps 5]

1. Rotation only (the thesis), ROI 256 and 800 cells: ``fast`` against the thesis's 380 evaluations written
   the straightforward fast way (one ``cv2.warpAffine`` nearest-neighbour per angle, numpy counts).
2. Rotation × translation, ROI 8 m, W 0.5 m (441 translations), centers 0.25 m off, generic centers and
   centers on cell centres and corners: ``fast`` against the compiled exhaustive search
   (:func:`merger.search.reference_search`: the same compiled counts at every angle and translation);
   cold (every cache cleared) and warm (the moving map's own arrays kept, as in a merge cycle).
Answers are checked against the baseline's in every run; the figures are medians (ms) after a warm-up
call (numba compiles on first use; the on-disk cache makes later processes start warm).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from merger.grid import FREE_S, OCCUPIED_S  # noqa: E402
from merger.search import (  # noqa: E402
    RotationProblem,
    clear_all,
    fast_search,
    fine_angles,
    reference_search,
    wrap_deg,
)
from merger.synthetic import arc_viewpoints, partial_view, robot_pose_on_circle, room_scene, window_case  # noqa: E402


def scaled_views(roi_m: float, seed: int, starts=(90.0, 210.0), arc: float = 35.0):
    """Local maps of a generated room scaled to the ROI (an 8 × 6 m room for a 12.8 m ROI)."""
    s = roi_m / 12.8
    rng = np.random.default_rng(seed)
    scene = room_scene(rng, room=(8.0 * s, 6.0 * s), room_center=(0.7 * s, 0.4 * s),
                       pillar_offset=(1.4 * s, 0.9 * s), pillar_radius=0.15 * max(s, 1.0))
    radius, reach = 1.8 * s, 5.6 * s
    maps = []
    for a in starts:
        pose = robot_pose_on_circle(a, radius, yaw_offset_deg=rng.uniform(-40, 40))
        g, c = partial_view(scene, pose, arc_viewpoints(a, arc, radius), size_m=1.25 * roi_m, range_m=reach,
                            beams=int(720 * max(1.0, s)), noise=0.002, rng=rng)
        maps.append((g, c))
    return maps


def opencv_brute_force(problem: RotationProblem) -> tuple[float, float]:
    """The thesis's 380 evaluations, written the straightforward fast way: the moving map's ROI square
    (cells whose centre lies inside it; unknown around), then for every angle one ``cv2.warpAffine``
    (nearest neighbour) of it onto the reference ROI lattice and numpy counts of ω̃ (agr̃, dis). The
    reference's scan: 1° over 360°, then 0.1° over ±1°, first maximum. Returns (θ, score): the
    reference's θ on the bench's scenes (checked in every run); the score may differ slightly (the square
    is masked by cell centres, and OpenCV's nearest lookups are fixed point)."""
    n, res = problem.n, problem.ref.resolution
    mov, rm = problem.moving, problem.moving.resolution
    ref = problem.ref_roi()
    ro, rf = ref == OCCUPIED_S, ref == FREE_S
    half = n * res / 2.0
    cx, cy = problem.center_moving
    # the moving ROI square, on the moving map's own cells (outside: unknown)
    xs = mov.origin[0] + (np.arange(mov.width) + 0.5) * rm - cx
    ys = mov.origin[1] + (np.arange(mov.height) + 0.5) * rm - cy
    src = np.where((np.abs(ys)[:, None] < half) & (np.abs(xs)[None, :] < half), mov.states, 0).astype(np.uint8)
    k0 = -(n - 1) / 2.0 * res  # the lattice's first offset (both axes)
    ux, uy = (cx - mov.origin[0]) / rm, (cy - mov.origin[1]) / rm

    def score(theta: float) -> float:
        t = np.radians(-theta)
        c, s = np.cos(t), np.sin(t)
        # lattice point (j, i) at offset k looks up the moving cell containing c_m + R(−θ) k:
        # cell coordinates u = (c_m − origin)/rm + R(−θ) k / rm; OpenCV's nearest pixel of u − 0.5 is floor(u)
        m = np.array([[c * res / rm, -s * res / rm, ux + (c - s) * k0 / rm - 0.5],
                      [s * res / rm, c * res / rm, uy + (s + c) * k0 / rm - 0.5]])
        out = cv2.warpAffine(src, m, (n, n), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                             borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        mo = out == OCCUPIED_S
        agree = np.count_nonzero(mo & ro)
        dis = np.count_nonzero((out == FREE_S) & ro) + np.count_nonzero(mo & rf)
        return agree / (agree + dis) if agree + dis else 0.0

    coarse = [score(float(a)) for a in range(360)]
    best = float(np.argmax(coarse))
    angles = fine_angles(best)
    fine = [score(float(a)) for a in angles]
    i = int(np.argmax(fine))
    return wrap_deg(float(angles[i])), fine[i]


def timed(fn, *args):
    t = time.perf_counter()
    out = fn(*args)
    return (time.perf_counter() - t) * 1e3, out


def median_ms(fn, problem_factory, reps: int, warm: bool = False):
    """Median wall time of ``fn`` on a new problem object per repetition: cold (every cache cleared, as a
    one-off ``merger align``), or ``warm`` (the moving map's own arrays kept, as in a merge cycle where a
    map is the moving map of several searches)."""
    out = None
    times = []
    for _ in range(reps):
        p = problem_factory()
        if not warm:
            clear_all()
        ms, out = timed(fn, p)
        times.append(ms)
    return statistics.median(times), out


def rotation_only(reps: int) -> None:
    print("1. rotation only: fast vs OpenCV brute force (ms, median)")
    for cells in (256, 800):
        roi = cells * 0.05
        (g0, c0), (g1, c1) = scaled_views(roi, 1)
        def make(g0=g0, g1=g1, c0=c0, c1=c1, roi=roi):
            return RotationProblem(g0, g1, c0, c1, roi, "similarity", 0.0)
        fast_search(make())  # warm-up
        bf_ms, bf = median_ms(opencv_brute_force, make, max(1, reps // 2))
        f_ms, f = median_ms(fast_search, make, reps)
        print(f"   ROI {cells}: brute force {bf_ms:8.1f}  fast {f_ms:7.2f}  ratio {bf_ms / f_ms:6.1f}x  "
              f"θ {f.theta_deg:.1f}° (brute force {bf[0]:.1f}°)")


def windowed(reps: int, seeds: int) -> None:
    print("2. ROI 8 m, W 0.5 m, centers 0.25 m off: fast vs compiled exhaustive (ms)")
    rows = []
    for seed in range(seeds):
        c = window_case(seed, "views", roi_m=(8.0, 8.0), window_m=(0.5, 0.5), error_frac=0.5)
        g = c.ref
        for mode in ("generic", "centre", "corner"):
            cr = np.array(c.center_ref)
            if mode != "generic":
                cr = np.array(g.origin) + (np.floor((cr - g.origin) / g.resolution) + (0.5 if mode == "centre" else 0)) * g.resolution
            def make(cr=cr, g=g, c=c):
                return RotationProblem(g, c.moving, tuple(cr), c.center_moving, 8.0, "similarity", 0.5)
            fast_search(make())
            f_ms, f = median_ms(fast_search, make, reps)
            w_ms, _ = median_ms(fast_search, make, reps, warm=True)
            ref_ms, r = median_ms(reference_search, make, 1) if seed < 2 else (float("nan"), f)
            same = (f.theta_deg, f.cells, f.score) == (r.theta_deg, r.cells, r.score)
            rows.append((mode, f_ms, ref_ms, w_ms))
            print(f"   seed {seed} {mode:7s}: fast {f_ms:7.1f} (warm {w_ms:5.1f})  exhaustive {ref_ms:8.1f}  "
                  f"same answer {same}  θ {f.theta_deg:.1f}° t {f.cells}")
    for mode in ("generic", "centre", "corner"):
        ms = [r[1] for r in rows if r[0] == mode]
        wm = [r[3] for r in rows if r[0] == mode]
        print(f"   {mode:7s}: fast median {statistics.median(ms):.1f} ms cold, {statistics.median(wm):.1f} ms warm "
              f"(the moving map's arrays cached) over {len(ms)} problems")
    gen = [r for r in rows if r[0] == "generic" and r[2] == r[2]]
    if gen:
        print(f"   ratio exhaustive / fast (generic): {statistics.median([r[2] / r[1] for r in gen]):.1f}x")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--seeds", type=int, default=6)
    args = ap.parse_args(argv)
    rotation_only(args.reps)
    windowed(args.reps, args.seeds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
