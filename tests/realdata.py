"""Real maps with their ground truth (the data in ``$CIRCSIM_REAL_MAPS``, by default ../shared/data/real-maps
beside the checkout, read in place: licences): the cases of ``benchmarks/real_maps.py`` and of the tests that need the data (which skip when it is absent).

Cases. Every ordered pair of one Halmstad building (ground truth: gt_pairs.csv, ±2–3°, ±0.5 m), at each
center error and ROI side; A.P. Hill's six pairs, the UC Merced runs and the demo pair, which have no
published truth, against an independent fit of each pair (:func:`estimate_truth`: correlation, then
ICP; no common center used), named "fit" (A.P. Hill's maps are roughly pre-aligned, yet the data's
SOURCE.md finds identity never their best shift). The common center is a point both maps saw: among the
moving map's occupied cells that land within 3 cells of the reference's occupied cells under the truth,
the one nearest their centroid. It is exact in the reference's frame; the moving map's copy gets the
center error, in a direction drawn from the case's seed. The window is W = max(0.5, 2 × error) (the
center error is then inside it). *Correct* = θ within 3° and the true center placed within 0.5 m (plus
the truth's own RMS where it has one).
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from merger.grid import FREE_S, OCCUPIED_S, OccupancyGrid
from merger.io.mapio import load_map
from merger.search import angle_diff_deg
from merger.transform import rotation

ENV = "CIRCSIM_REAL_MAPS"  # the folder holding halmstad/, carpin-ucmerced/, sunil-demo/ (default: beside the checkout)


def data_folder(environ=os.environ) -> Path:
    """The shared real maps' folder: ``$CIRCSIM_REAL_MAPS``, else ``../shared/data/real-maps`` beside the
    checkout (where the project's machines keep it)."""
    if environ.get(ENV):
        return Path(environ[ENV]).expanduser()
    return Path(__file__).resolve().parents[2] / "shared" / "data" / "real-maps"


DATA = data_folder()
MISSING = (f"the shared real maps are not at {DATA} (no halmstad/gt_pairs.csv): set {ENV} to the folder "
           "holding them (their licences keep them out of the repository: docs/merging-real-maps.md)")


def have_data() -> bool:
    return (DATA / "halmstad" / "gt_pairs.csv").exists()


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
    return icp(ref, mov, th, t, icp_iters)


def icp(ref: OccupancyGrid, mov: OccupancyGrid, th: float, t, iters: int = 40, max_m=(0.3,)):
    """Point-to-point ICP of the moving map's occupied cells onto the reference's from x_ref = R(θ) x_mov + t:
    each iteration pairs every moving cell with its nearest occupied reference cell within the schedule's
    distance (``max_m``: one distance per block of ``iters`` iterations, e.g. (1.0, 0.5, 0.3, 0.15) to start
    from a coarse truth) and fits the rigid motion in closed form. Returns (θ°, (tx, ty), inlier RMS m,
    inlier fraction) of the last iteration."""
    b = occupied_xy(mov)
    t = np.asarray(t, np.float64)
    dist, lab = cv2.distanceTransformWithLabels(np.where(ref.states == OCCUPIED_S, 0, 255).astype(np.uint8),
                                                cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL)
    zr, zc = np.nonzero(ref.states == OCCUPIED_S)
    lab_xy = np.zeros((lab.max() + 1, 2))
    lab_xy[lab[zr, zc]] = np.stack([ref.origin[0] + (zc + 0.5) * ref.resolution,
                                    ref.origin[1] + (zr + 0.5) * ref.resolution], 1)
    rms, frac = float("nan"), 0.0
    for lim in [m for m in max_m for _ in range(iters)]:
        p = b @ rotation(th).T + t
        cc = np.floor((p[:, 0] - ref.origin[0]) / ref.resolution).astype(np.int64)
        rr = np.floor((p[:, 1] - ref.origin[1]) / ref.resolution).astype(np.int64)
        ok = (rr >= 0) & (rr < ref.height) & (cc >= 0) & (cc < ref.width)
        ok[ok] &= dist[rr[ok], cc[ok]] * ref.resolution <= lim
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


REFINE_SCHEDULE_M = (1.0, 0.5, 0.3, 0.15)  # ICP's pairing distance from the keypoint truth (±0.5 m) down
_REFINED: dict[tuple, tuple] = {}


def refined_truth(case: Case):
    """The case's truth refined by :func:`icp` on the two maps (schedule ``REFINE_SCHEDULE_M``, 20 iterations
    each): (case with that truth, ICP RMS m, inlier fraction). The keypoint truth of Halmstad is good to its
    RMS (0.2–1.1 m); the refined one is where the whole maps fit best near it. None without a truth."""
    if case.truth is None:
        return None
    th, tt = case.truth
    # the case's truth in world form x_ref = R(θ) x_mov + t_w: t_w = c_ref + t − R(θ) c_mov
    tw = np.asarray(case.c_ref) + np.asarray(tt) - rotation(th) @ np.asarray(case.c_mov)
    key = (case.ref, case.mov, round(th, 9), round(float(tw[0]), 9), round(float(tw[1]), 9))
    if key not in _REFINED:
        _REFINED[key] = icp(grid(case.ref), grid(case.mov), th, tw, 20, REFINE_SCHEDULE_M)
    th2, tw2, rms, frac = _REFINED[key]
    t2 = rotation(th2) @ np.asarray(case.c_mov) + np.asarray(tw2) - np.asarray(case.c_ref)
    return (replace(case, truth=(th2 % 360.0, (float(t2[0]), float(t2[1]))),
                    tol=(THETA_TOL_DEG, CENTER_TOL_M)), rms, frac)


def placement_error(case: Case, theta: float, t) -> tuple[float, float]:
    """(|θ − θ*|°, m) of a placement against the case's truth: the angle error and how far from c_ref the
    true moving center lands (the distance :func:`correct` judges)."""
    th, tt = case.truth
    off = np.asarray(t, np.float64) - rotation(theta) @ (rotation(-th) @ np.asarray(tt, np.float64))
    return abs(angle_diff_deg(theta, th)), float(np.hypot(*off))


def correct(case: Case, theta: float, t) -> bool | None:
    if case.truth is None:
        return None
    th, tt = case.truth
    # where the true moving center c_mov − e lands (c_ref + t − R(θ)e), against c_ref; e = R(−θ*)t*
    off = np.asarray(t, np.float64) - rotation(theta) @ (rotation(-th) @ np.asarray(tt, np.float64))
    return abs(angle_diff_deg(theta, th)) <= case.tol[0] and float(np.hypot(*off)) <= case.tol[1]


# ---------------------------------------------------------------------------------------------- evidence probe
