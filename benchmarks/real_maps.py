"""Benchmark: merging real maps from independent runs (the data in ../shared/data/real-maps).

Run from the repository root::

    python benchmarks/real_maps.py --data ../shared/data/real-maps
    python benchmarks/real_maps.py --sets halmstad --roi 16 --errors 0,0.5 --json out.json

Cases. Every ordered pair of one Halmstad building (ground truth: gt_pairs.csv, ±2–3°, ±0.5 m), at each
center error and ROI side; A.P. Hill's six pairs, the UC Merced runs and the demo pair, which have no
published truth, against an independent fit of each pair (:func:`estimate_truth`: correlation, then
ICP; no common center used), printed as "fit" (A.P. Hill's maps are roughly pre-aligned, yet the data's
SOURCE.md finds identity never their best shift: the fit's distance from identity is printed too).
The common center is a point both maps saw: among the moving map's occupied cells that land within 3
cells of the reference's occupied cells under the truth, the one nearest their centroid. It is exact in
the reference's frame; the moving map's copy gets the center error, in a direction drawn from the
case's seed. The window is W = max(0.5, 2 × error) (the center error is then inside it).

Each case is merged as a two-map team (:func:`merger.merge_team`, default parameters unless set) and
scored against the truth: *correct* = θ within 3° and the true center placed within 0.5 m. It prints
correct-accepted / false (accepted, not correct) / refused (split by whether the refused answer was
right) and the median and worst wall times; the same figures for a feature-matching baseline (ORB
features, RANSAC similarity fit and the confidence rule of OpenCV's stitching / ROS m-explore's
map_merge, which the ROS ecosystem ships for maps without a common center).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from merger import MapInput, MergeParams, merge_team  # noqa: E402
from merger.grid import FREE_S, OCCUPIED_S, OccupancyGrid  # noqa: E402
from merger.io.mapio import load_map  # noqa: E402
from merger.search import angle_diff_deg  # noqa: E402
from merger.team.orders import Warps  # noqa: E402
from merger.team.verify import verify_contrast  # noqa: E402
from merger.transform import overlap, rotation  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "real-maps"
THETA_TOL_DEG = 3.0  # a placement is correct within this angle ...
CENTER_TOL_M = 0.5  # ... and with the true center placed within this distance (plus the truth's own RMS)


@dataclass(frozen=True)
class Case:
    name: str
    ref: str  # map paths (YAML)
    mov: str
    c_ref: tuple[float, float]
    c_mov: tuple[float, float]  # with the center error
    truth: tuple[float, tuple[float, float]] | None  # (θ, t) in the search's convention, None: unknown
    roi_m: float
    window_m: float
    error_m: float
    tol: tuple[float, float] = (THETA_TOL_DEG, CENTER_TOL_M)


_MAPS: dict[str, OccupancyGrid] = {}


def grid(path: str) -> OccupancyGrid:
    if path not in _MAPS:
        _MAPS[path] = load_map(path)
    return _MAPS[path]


def occupied_xy(g: OccupancyGrid) -> np.ndarray:
    """World (x, y) of the occupied cells' centres."""
    r, c = np.nonzero(g.states == OCCUPIED_S)
    return np.stack([g.origin[0] + (c + 0.5) * g.resolution, g.origin[1] + (r + 0.5) * g.resolution], 1)


def near_occupied(g: OccupancyGrid, xy: np.ndarray, cells: float) -> np.ndarray:
    """Whether each point lies within ``cells`` cells of an occupied cell of ``g``."""
    dist = cv2.distanceTransform(np.where(g.states == OCCUPIED_S, 0, 255).astype(np.uint8), cv2.DIST_L2, 5)
    c = np.floor((xy[:, 0] - g.origin[0]) / g.resolution).astype(np.int64)
    r = np.floor((xy[:, 1] - g.origin[1]) / g.resolution).astype(np.int64)
    ok = (r >= 0) & (r < g.height) & (c >= 0) & (c < g.width)
    out = np.zeros(len(xy), bool)
    out[ok] = dist[r[ok], c[ok]] <= cells
    return out


def common_point(mov: OccupancyGrid, ref: OccupancyGrid, theta: float, t) -> tuple[float, float] | None:
    """A point both maps saw, in the moving map's frame (see the module's docstring)."""
    xy = occupied_xy(mov)
    placed = xy @ rotation(theta).T + np.asarray(t)
    both = xy[near_occupied(ref, placed, 3.0)]
    if len(both) < 50:
        return None
    mid = both.mean(0)
    return tuple(float(v) for v in both[np.argmin(((both - mid) ** 2).sum(1))])


def pair_case(name, ref_path, mov_path, theta, t_world, roi, err, seed, tol=(THETA_TOL_DEG, CENTER_TOL_M),
              known=True):
    """A case from a world-frame truth x_ref = R(θ) x_mov + t_world."""
    ref, mov = grid(ref_path), grid(mov_path)
    c_mov = common_point(mov, ref, theta, t_world)
    if c_mov is None:
        return None
    c_ref = tuple(float(v) for v in rotation(theta) @ np.asarray(c_mov) + np.asarray(t_world))
    a = np.random.default_rng(seed).uniform(0, 2 * math.pi)
    e = np.array([math.cos(a), math.sin(a)]) * err
    c_mov_err = (c_mov[0] + float(e[0]), c_mov[1] + float(e[1]))
    # x_ref = c_ref + t + R(θ)(x − c_mov_err) is the truth when t = R(θ)(c_mov_err − c_mov)
    t = rotation(theta) @ e
    truth = (theta % 360.0, (float(t[0]), float(t[1]))) if known else None
    return Case(name, ref_path, mov_path, c_ref, c_mov_err, truth, roi, max(0.5, 2 * err), err, tol)


def halmstad_cases(data: Path, rois, errors):
    rows = list(csv.DictReader(open(data / "halmstad" / "gt_pairs.csv")))
    out = []
    for k, row in enumerate(rows):
        a, b = row["map_a"], row["map_b"]  # p_b = R p_a + t: b is the reference, a moves
        for roi in rois:
            for err in errors:
                # the keypoint fit is itself uncertain by its RMS residual (0.2–1.1 m): a placement within
                # 0.5 m of it plus that RMS is as right as the truth can tell
                rms_m = float(row["rms_px"]) * float(row["tx_m"]) / float(row["tx_px"])
                c = pair_case(f"halmstad {a}->{b}", str(data / "halmstad" / f"{b}.yaml"),
                              str(data / "halmstad" / f"{a}.yaml"), float(row["theta_deg"]),
                              (float(row["tx_m"]), float(row["ty_m"])), roi, err, 1000 * k + int(100 * err),
                              (THETA_TOL_DEG, CENTER_TOL_M + rms_m))
                if c is not None:
                    out.append(c)
    return out


def aphill_pairs(data: Path):
    """A.P. Hill's six pairs (name, reference YAML, moving YAML): robot i moves onto robot j > i."""
    d = data / "carpin-ucmerced"
    return [(f"{i}->{j}", str(d / f"aphill_robot{j}.yaml"), str(d / f"aphill_robot{i}.yaml"))
            for i in range(4) for j in range(i + 1, 4)]


def aphill_cases(data: Path, rois, errors):
    return fitted_cases(data, rois, errors, aphill_pairs(data), "aphill")


def _raster(xy: np.ndarray, lo: np.ndarray, cell: float, shape) -> np.ndarray:
    img = np.zeros(shape, np.float32)
    ij = np.floor((xy - lo) / cell).astype(np.int64)
    ok = (ij[:, 0] >= 0) & (ij[:, 0] < shape[1]) & (ij[:, 1] >= 0) & (ij[:, 1] < shape[0])
    np.add.at(img, (ij[ok, 1], ij[ok, 0]), 1.0)
    return img


def estimate_truth(ref: OccupancyGrid, mov: OccupancyGrid, cell: float = 0.2, icp_iters: int = 40):
    """An independent estimate of x_ref = R(θ) x_mov + t for maps without a published truth (no common
    center used): every whole degree, the translation maximising the moving map's occupied points on the
    reference's occupied cells minus those on its free cells (both at ``cell`` metres, occupied dilated
    by one coarse cell), by FFT cross-correlation; the best is refined by point-to-point ICP on the
    occupied cells (nearest occupied reference cell within 0.3 m, closed-form rigid fit). Returns
    (θ°, (tx, ty), inlier RMS m, inlier fraction) — a fit, named as such in the output, not a truth."""
    a, b = occupied_xy(ref), occupied_xy(mov)
    lo = np.array(ref.origin, np.float64)
    shape = (int(math.ceil(ref.height * ref.resolution / cell)) + 1, int(math.ceil(ref.width * ref.resolution / cell)) + 1)
    occ = cv2.dilate((_raster(a, lo, cell, shape) > 0).astype(np.uint8), np.ones((3, 3), np.uint8)).astype(np.float32)
    fr = ref.states == FREE_S
    r, c = np.nonzero(fr)
    free_xy = np.stack([ref.origin[0] + (c + 0.5) * ref.resolution, ref.origin[1] + (r + 0.5) * ref.resolution], 1)
    free = (_raster(free_xy, lo, cell, shape) > 0).astype(np.float32) * (occ == 0)
    target = occ - free
    bm = b - b.mean(0)
    ph, pw = 2 * shape[0], 2 * shape[1]
    ft = np.fft.rfft2(target, (ph, pw))
    best = (-np.inf, 0.0, np.zeros(2))
    for th in range(360):
        q = bm @ rotation(float(th)).T
        qlo = q.min(0)
        img = _raster(q, qlo, cell, (int((q[:, 1].max() - qlo[1]) / cell) + 2, int((q[:, 0].max() - qlo[0]) / cell) + 2))
        if img.shape[0] > ph or img.shape[1] > pw:
            continue
        corr = np.fft.irfft2(ft * np.conj(np.fft.rfft2(img, (ph, pw))), (ph, pw))
        k = int(np.argmax(corr))
        dy, dx = divmod(k, pw)
        dy = dy - ph if dy > ph // 2 else dy
        dx = dx - pw if dx > pw // 2 else dx
        if corr.flat[k] > best[0]:
            # the moving image's pixel (0, 0) lands on target pixel (dy, dx): x_ref = q + lo + d·cell − qlo
            best = (float(corr.flat[k]), float(th), lo + np.array([dx, dy]) * cell - qlo)
    _, th, t = best
    t = t - rotation(th) @ b.mean(0)  # applied to b itself (not centred)
    # ICP on the full-resolution occupied cells
    dist, lab = cv2.distanceTransformWithLabels(np.where(ref.states == OCCUPIED_S, 0, 255).astype(np.uint8),
                                                cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL)
    zr, zc = np.nonzero(ref.states == OCCUPIED_S)
    lab_xy = np.zeros((lab.max() + 1, 2))
    lab_xy[lab[zr, zc]] = np.stack([ref.origin[0] + (zc + 0.5) * ref.resolution,
                                    ref.origin[1] + (zr + 0.5) * ref.resolution], 1)
    rms, frac = float("nan"), 0.0
    for _ in range(icp_iters):
        p = b @ rotation(th).T + t
        cc = np.floor((p[:, 0] - ref.origin[0]) / ref.resolution).astype(np.int64)
        rr = np.floor((p[:, 1] - ref.origin[1]) / ref.resolution).astype(np.int64)
        ok = (rr >= 0) & (rr < ref.height) & (cc >= 0) & (cc < ref.width)
        ok[ok] &= dist[rr[ok], cc[ok]] * ref.resolution <= 0.3
        if ok.sum() < 10:
            break
        src, dst = b[ok], lab_xy[lab[rr[ok], cc[ok]]]
        ms, md = src.mean(0), dst.mean(0)
        u, _, vt = np.linalg.svd((src - ms).T @ (dst - md))
        rot = (u @ vt).T
        if np.linalg.det(rot) < 0:
            vt[-1] *= -1
            rot = (u @ vt).T
        th = math.degrees(math.atan2(rot[1, 0], rot[0, 0])) % 360.0
        t = md - rotation(th) @ ms
        rms = float(np.sqrt(((src @ rotation(th).T + t - dst) ** 2).sum(1).mean()))
        frac = float(ok.mean())
    return th, (float(t[0]), float(t[1])), rms, frac


_FITS: dict[tuple[str, str], tuple] = {}


def fitted_truth(ref_path: str, mov_path: str):
    """:func:`estimate_truth` of a pair of map files, computed once per run."""
    if (ref_path, mov_path) not in _FITS:
        _FITS[ref_path, mov_path] = estimate_truth(grid(ref_path), grid(mov_path))
    return _FITS[ref_path, mov_path]


def fitted_cases(data: Path, rois, errors, pairs, label: str, tol=(THETA_TOL_DEG, CENTER_TOL_M)):
    """Cases of map pairs without a published truth, scored against :func:`estimate_truth` (named
    "fit" in the output): ``pairs`` = (name, reference YAML, moving YAML)."""
    out = []
    for k, (name, ref_path, mov_path) in enumerate(pairs):
        th, t, rms, frac = fitted_truth(ref_path, mov_path)
        print(f"{label} {name}: fitted θ {th:.2f}° ({angle_diff_deg(th, 0.0):+.2f}° from identity), t ({t[0]:+.2f}, "
              f"{t[1]:+.2f}) m, ICP RMS {rms:.3f} m on {100 * frac:.0f}% of the moving map's occupied cells",
              flush=True)
        for roi in rois:
            for err in errors:
                c = pair_case(f"{label} {name}", ref_path, mov_path, th, t, roi, err, 9000 + 1000 * k + int(100 * err),
                              tol)
                if c is not None:
                    out.append(c)
    return out


def ucmerced_cases(data: Path, rois, errors):
    d = data / "carpin-ucmerced"
    pairs = [("longrun 7->6", str(d / "ucm_longrun6.yaml"), str(d / "ucm_longrun7.yaml")),
             ("longcorridor 2->1", str(d / "ucm_longcorridor1.yaml"), str(d / "ucm_longcorridor2.yaml"))]
    return fitted_cases(data, rois, errors, pairs, "ucmerced")


def demo_cases(data: Path, rois, errors):
    d = data / "sunil-demo"
    return fitted_cases(data, rois, errors, [("2->1", str(d / "demo_1.yaml"), str(d / "demo_2.yaml"))], "demo")


def correct(case: Case, theta: float, t) -> bool | None:
    if case.truth is None:
        return None
    th, tt = case.truth
    # where the true moving center c_mov − e lands (c_ref + t − R(θ)e), against c_ref; e = R(−θ*)t*
    off = np.asarray(t, np.float64) - rotation(theta) @ (rotation(-th) @ np.asarray(tt, np.float64))
    return abs(angle_diff_deg(theta, th)) <= case.tol[0] and float(np.hypot(*off)) <= case.tol[1]


# ---------------------------------------------------------------------------------------------- evidence probe
def tolerant_counts(a: np.ndarray, b: np.ndarray, r: float):
    """(ā, dis_r) of two overlapped state arrays: agreement within r cells, disagreement beyond it."""
    occ_a, occ_b = a == OCCUPIED_S, b == OCCUPIED_S
    free_a, free_b = a == FREE_S, b == FREE_S
    if r <= 0:
        near_b, near_a = occ_b, occ_a
    else:
        da = cv2.distanceTransform(np.where(occ_a, 0, 255).astype(np.uint8), cv2.DIST_L2, 5)
        db = cv2.distanceTransform(np.where(occ_b, 0, 255).astype(np.uint8), cv2.DIST_L2, 5)
        near_a, near_b = da <= r, db <= r
    agr = (np.count_nonzero(occ_a & near_b) + np.count_nonzero(occ_b & near_a)) / 2
    dis = np.count_nonzero(occ_a & free_b & ~near_b) + np.count_nonzero(occ_b & free_a & ~near_a)
    return agr, dis


def probe(case: Case, theta, t, radii=(0, 1, 2, 3)):
    maps = [MapInput("ref", grid(case.ref), case.c_ref), MapInput("mov", grid(case.mov), case.c_mov)]
    w = Warps(maps)
    a, b = overlap(maps[0].grid, w.get(0, 1, theta, t))
    out = {}
    for r in radii:
        agr, dis = tolerant_counts(a, b, r)
        out[f"nu{r}"] = agr / (agr + dis) if agr + dis else 0.0
        out[f"sup{r}"] = agr + dis
    return out


# ------------------------------------------------------------------------------------------ feature baseline
ORB_FEATURES = 1500
MATCH_RATIO = 0.7  # OpenCV stitching's BestOf2NearestMatcher: match_conf 0.3 → ratio 1 − 0.3
CONFIDENCE_MIN = 1.0  # m-explore map_merge's estimation_confidence default


def _image(g: OccupancyGrid) -> np.ndarray:
    """The grid as m-explore hands it to OpenCV: occupied 100, free 0, unknown 255 (int8 −1 as uint8)."""
    return np.choose(g.states, [255, 0, 100]).astype(np.uint8)


def feature_match(case: Case):
    """(accepted, θ, where the true moving center lands − c_ref) of an ORB + RANSAC similarity fit with the
    stitching confidence inliers / (8 + 0.3 · matches) ≥ 1 (ROS m-explore map_merge's rule)."""
    ref, mov = grid(case.ref), grid(case.mov)
    orb = cv2.ORB_create(ORB_FEATURES)
    k1, d1 = orb.detectAndCompute(_image(mov), None)
    k2, d2 = orb.detectAndCompute(_image(ref), None)
    if d1 is None or d2 is None or len(k1) < 3 or len(k2) < 3:
        return False, None, None
    pairs = cv2.BFMatcher(cv2.NORM_HAMMING).knnMatch(d1, d2, k=2)
    good = [m[0] for m in pairs if len(m) == 2 and m[0].distance < MATCH_RATIO * m[1].distance]
    if len(good) < 3:
        return False, None, None
    src = np.float32([k1[m.queryIdx].pt for m in good])
    dst = np.float32([k2[m.trainIdx].pt for m in good])
    a, inl = cv2.estimateAffinePartial2D(src, dst, method=cv2.RANSAC, ransacReprojThreshold=3.0)
    if a is None:
        return False, None, None
    conf = int(inl.sum()) / (8 + 0.3 * len(good))
    theta = math.degrees(math.atan2(a[1, 0], a[0, 0])) % 360.0  # rows grow with y: no flip, same angle
    if case.truth is None:
        return conf >= CONFIDENCE_MIN, theta, None
    e = rotation(-case.truth[0]) @ np.asarray(case.truth[1])  # the center error
    cm = np.asarray(case.c_mov) - e  # the true moving center, world
    px = (cm - np.asarray(mov.origin)) / mov.resolution - 0.5
    q = a[:, :2] @ px + a[:, 2]
    landed = np.asarray(ref.origin) + (q + 0.5) * ref.resolution
    return conf >= CONFIDENCE_MIN, theta, float(np.hypot(*(landed - np.asarray(case.c_ref))))


def run_case(case: Case, params: MergeParams, probes: bool):
    # the reference map first: results in its frame (merge_team ranks maps by name for the orders)
    maps = [MapInput("a_ref", grid(case.ref), case.c_ref), MapInput("b_mov", grid(case.mov), case.c_mov)]
    p = replace(params, roi_m=case.roi_m, window_m=case.window_m)
    t0 = time.perf_counter()
    res = merge_team(maps, p)
    ms = (time.perf_counter() - t0) * 1e3
    top = res.top
    th, t = top.theta_deg["b_mov"], top.translation("b_mov")
    step = top.steps[0][1]
    row = {"case": case.name, "roi": case.roi_m, "err": case.error_m, "window": case.window_m,
           "theta": th, "t": list(t), "accepted": res.accepted, "correct": correct(case, th, t),
           "reason": res.reason, "nu": top.nu_sum, "support": sum(c.support for c in top.checks.values()),
           "score": step.score, "runner_up": step.runner_up_score, "roi_support": step.counts.support,
           "ms": ms, "truth": None if case.truth is None else [case.truth[0], list(case.truth[1])]}
    # the contrast rule on the same placement (the search is the same: only the verification differs)
    t1 = time.perf_counter()
    w = Warps(maps)
    v = verify_contrast(maps[0].grid, w.get(0, 1, th, t), (case.c_ref[0] + t[0], case.c_ref[1] + t[1]),
                        tolerance_m=p.tolerance_m, contrast_min=p.contrast_min, min_support=p.min_support)
    has = step.has_evidence
    row["contrast"] = {"accepted": bool(v.passed and has and not res.ambiguity), "correct": row["correct"],
                       "value": v.contrast.contrast, "ms": (time.perf_counter() - t1) * 1e3}
    if case.truth is not None:
        tt = case.truth[1]
        off = np.asarray(t, np.float64) - rotation(th) @ (rotation(-case.truth[0]) @ np.asarray(tt, np.float64))
        row["center_off_m"] = float(np.hypot(*off))
        row["theta_err"] = abs(angle_diff_deg(th, case.truth[0]))
    acc, fth, foff = feature_match(case)
    row["feature"] = {"accepted": acc, "theta": fth, "center_off_m": foff,
                      "correct": None if case.truth is None or fth is None else
                      abs(angle_diff_deg(fth, case.truth[0])) <= case.tol[0] and foff <= case.tol[1]}
    if probes:
        row["found"] = probe(case, th, t)
        others = [probe(case, (th + d) % 360.0, t, radii=(0, 2)) for d in range(30, 360, 30)]
        row["others"] = {k: [o[k] for o in others] for k in others[0]}
        if case.truth is not None:
            row["at_truth"] = probe(case, case.truth[0], case.truth[1])
    return row


def aphill_team(data: Path, roi: float, verification: str) -> str:
    """The four A.P. Hill robots merged as one team (strategy auto: the tree for four maps), the center a
    point all four saw (the maps are roughly pre-aligned: the same coordinates in every frame); correct =
    every map placed as its pair fit onto robot 0 places it (θ within 3°, the center within 0.5 m)."""
    d = data / "carpin-ucmerced"
    paths = [str(d / f"aphill_robot{i}.yaml") for i in range(4)]
    g = [grid(p) for p in paths]
    xy = occupied_xy(g[0])
    seen = np.ones(len(xy), bool)
    for other in g[1:]:
        seen &= near_occupied(other, xy, 3.0)
    both = xy[seen]
    c = tuple(float(v) for v in both[np.argmin(((both - both.mean(0)) ** 2).sum(1))])
    maps = [MapInput(f"r{i}", gi, c) for i, gi in enumerate(g)]
    t0 = time.perf_counter()
    res = merge_team(maps, MergeParams(roi_m=roi, verification=verification))
    ms = (time.perf_counter() - t0) * 1e3
    top = res.top
    ok = True
    for i, m in enumerate(maps[1:], start=1):
        th, t, _, _ = fitted_truth(paths[0], paths[i])  # x_0 = R(θ) x_i + t
        # the team places map i's center c at c + translation; the fit places it at R(θ) c + t
        landed = np.asarray(c) + np.asarray(top.translation(m.name))
        off = float(np.hypot(*(landed - (rotation(th) @ np.asarray(c) + np.asarray(t)))))
        ok &= abs(angle_diff_deg(top.theta_deg[m.name], th)) <= THETA_TOL_DEG and off <= CENTER_TOL_M
    return (f"aphill four-robot team, ROI {roi:g} m, {verification}: accepted {res.accepted}, correct {ok}, "
            f"{ms:.0f} ms" + ("" if res.accepted else f" ({res.reason[:160]})"))


def demo_overlays(data: Path, out: Path) -> list[str]:
    """The demo pair (MIT licence: its overlays may be shown) merged at ROI 8 m: centers 0.25 m off with
    the window 0.5 m (accepted), and 1.0 m off with the same window — the centers trusted more than they
    deserve (refused; written as the merger's ``--force`` writes it). Writes DIR/demo_accepted_overlay.png
    and DIR/demo_refused_overlay.png; returns one line per case."""
    from merger.cli import merge_files, write_files

    d = data / "sunil-demo"
    ref_path, mov_path = str(d / "demo_1.yaml"), str(d / "demo_2.yaml")
    th, t, _, _ = fitted_truth(ref_path, mov_path)
    lines = []
    for label, err, window in (("accepted", 0.25, 0.5), ("refused", 1.0, 0.5)):
        c = pair_case("demo 2->1", ref_path, mov_path, th, t, 8.0, err, 9000 + int(100 * err))
        c = replace(c, window_m=window)
        maps = [MapInput("demo_1", grid(c.ref), c.c_ref), MapInput("demo_2", grid(c.mov), c.c_mov)]
        res = merge_team(maps, MergeParams(roi_m=c.roi_m, window_m=c.window_m))
        top = res.top
        files = merge_files(res, maps, out / f"demo_{label}", force=True)
        write_files({k: v for k, v in files.items() if k.name.endswith("_overlay.png")})
        lines.append(f"demo 2->1, center error {err:g} m, W {window:g} m: accepted {res.accepted}, θ "
                     f"{top.theta_deg['demo_2']:.2f}° (fit {th:.2f}°), correct {correct(c, top.theta_deg['demo_2'], top.translation('demo_2'))}"
                     + ("" if res.accepted else f", refused: {res.reason}"))
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=DATA)
    ap.add_argument("--sets", default="halmstad,aphill,ucmerced,demo")
    ap.add_argument("--roi", default="8,16")
    ap.add_argument("--errors", default="0,0.25,0.5")
    ap.add_argument("--probes", action="store_true")
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--json", type=Path)
    ap.add_argument("--overlays", type=Path, metavar="DIR",
                    help="only write the demo pair's overlays (an accepted and a refused case) into DIR")
    args = ap.parse_args(argv)
    if args.overlays:
        for line in demo_overlays(args.data, args.overlays):
            print(line)
        return 0
    rois = [float(v) for v in args.roi.split(",")]
    errors = [float(v) for v in args.errors.split(",")]
    cases = []
    for s in args.sets.split(","):
        cases += {"halmstad": halmstad_cases, "aphill": aphill_cases, "ucmerced": ucmerced_cases,
                  "demo": demo_cases}[s](args.data, rois, errors)
    if args.limit:
        cases = cases[:args.limit]
    rows = []
    for c in cases:
        row = run_case(c, MergeParams(), args.probes)
        rows.append(row)
        print(f"{row['case']:24s} roi {row['roi']:4.0f} err {row['err']:.2f}: θ {row['theta']:7.2f} "
              f"(truth {row['truth'][0] if row['truth'] else float('nan'):7.2f}) acc {row['accepted']!s:5} "
              f"ok {row['correct']!s:5} ν {row['nu']:.3f} sup {row['support']:6d} score {row['score']:.3f} "
              f"ru {row['runner_up']:.3f} {row['ms']:7.0f} ms dθ {row.get('theta_err', -1):.2f} dc {row.get('center_off_m', -1):.2f} "
              + (" ".join(f"{k}={v:.3f}" for k, v in row.get('found', {}).items() if k.startswith('nu')))
              + (" | truth " + " ".join(f"{k}={v:.3f}" for k, v in row.get('at_truth', {}).items()
                                        if k.startswith('nu')) if 'at_truth' in row else ""), flush=True)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    print()
    print(summary(rows))
    if "aphill" in args.sets and not args.limit:
        for roi in rois:
            for verification in ("whole_map", "contrast"):
                print(aphill_team(args.data, roi, verification), flush=True)
    return 0


def tally(rows, key=None):
    """(cases, correct-accepted, false, refused right, refused wrong, unscored accepted)."""
    n = ca = fa = rr = rw = ua = 0
    for r in rows:
        acc, ok = (r["accepted"], r["correct"]) if key is None else (r[key]["accepted"], r[key]["correct"])
        n += 1
        if acc and ok is None:
            ua += 1
        elif acc:
            ca += ok
            fa += not ok
        else:
            rr += bool(ok)
            rw += not ok
    return n, ca, fa, rr, rw, ua


def summary(rows) -> str:
    groups: dict[tuple, list] = {}
    for r in rows:
        groups.setdefault((r["case"].split()[0], r["roi"], r["err"]), []).append(r)
    head = (f"{'set':9s} {'ROI':>4s} {'err':>5s} {'pairs':>5s} | {'ν_min rule: ok':>14s} {'false':>5s} {'refused':>7s} | "
            f"{'contrast: ok':>12s} {'false':>5s} {'refused':>7s} | {'features: ok':>12s} {'false':>5s} | "
            f"{'search ms (median, max)':>23s}")
    lines = [head, "-" * len(head)]
    for (name, roi, err), rs in sorted(groups.items()):
        n, ca, fa, rr, rw, ua = tally(rs)
        _, kca, kfa, krr, krw, _ = tally(rs, "contrast")
        _, fca, ffa, _, _, fua = tally(rs, "feature")
        ms = np.array([r["ms"] for r in rs])
        lines.append(f"{name:9s} {roi:4.0f} {err:5.2f} {n:5d} | {ca:14d} {fa:5d} {rr + rw:7d} | {kca:12d} {kfa:5d} "
                     f"{krr + krw:7d} | {fca:12d} {ffa:5d} | {np.median(ms):11.0f} {ms.max():11.0f}"
                     + (f"  (no truth: accepted {ua} / features {fua})" if ua or fua else ""))
    lines.append("ok = accepted and correct (θ within 3°, the true center within 0.5 m + the truth's RMS); "
                 "false = accepted and not correct; refused = not accepted")
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
