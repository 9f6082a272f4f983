"""``algorithm: features`` — the pipeline of ROS m-explore's ``map_merge`` (J. Hörner, 2016), which the ROS
ecosystem ships for maps without known initial poses. It uses no center.

Written from its source as read (github.com/hrnr/m-explore, ``map_merge/src/combine_grids/
merging_pipeline.cpp`` — ``MergingPipeline::estimateTransforms`` — and the backported
``opencv_backport/stitching/matchers.cpp``, ``AffineBestOf2NearestMatcher::match``), not copied:

1. each grid becomes an 8-bit image as the pipeline hands it to OpenCV, the ROS int8 cells read as bytes:
   occupied 100, free 0, unknown 255;
2. ORB features on each image (OpenCV's stitching ``OrbFeaturesFinder``: 1500 features);
3. matching as OpenCV's stitching ``BestOf2NearestMatcher`` (``match_conf`` 0.3): the two nearest
   descriptors (Hamming), kept when the nearest is closer than (1 − 0.3) × the second, in both
   directions, the union of the two;
4. fewer than ``num_matches_thresh1`` = 6 matches: no estimate; else a RANSAC partial-affine fit
   (``cv2.estimateAffinePartial2D``: rotation, uniform scale, translation; 3-pixel threshold);
5. the confidence of Brown and Lowe's stitching, inliers / (8 + 0.3 × matches) — accepted when at least
   ``estimation_confidence`` (map_merge's default 1.0; ``leaveBiggestComponent`` keeps pairs at or
   above it).

The placement is the fit's rotation and where it puts the moving map's center (its scale, near 1 for two
maps of one resolution, is reported as evidence). ``map_merge`` then chains the pairs into one frame
(OpenCV's affine estimator and bundle adjuster); the team here is assembled along a maximum spanning tree
of the accepted pairs by confidence (:mod:`merger.algorithms.team`), without the bundle adjustment.
Deterministic: OpenCV's RANSAC is seeded (``cv2.setRNGSeed``) before every fit.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..grid import OccupancyGrid
from .base import PairAnswer, center_form, refused

ORB_FEATURES = 1500  # OpenCV's stitching OrbFeaturesFinder default
MATCH_CONF = 0.3  # BestOf2NearestMatcher's match_conf: the ratio test keeps d1 < (1 - 0.3) d2
NUM_MATCHES_THRESH1 = 6  # fewer matches: no transform is estimated
RANSAC_REPROJ_PX = 3.0  # estimateAffinePartial2D's default threshold
CONFIDENCE_MIN = 1.0  # map_merge's estimation_confidence default
ORB_EDGE_PX = 31  # ORB's edgeThreshold (OpenCV's default): no keypoint nearer the border
MIN_SIDE = 2 * ORB_EDGE_PX + 1  # a map narrower has no feature (and OpenCV's pyramid fails on 1 cell)


def image(g: OccupancyGrid) -> np.ndarray:
    """The grid as m-explore hands it to OpenCV: occupied 100, free 0, unknown 255 (int8 −1 as a byte)."""
    return np.choose(g.states, [255, 0, 100]).astype(np.uint8)


def _features(g: OccupancyGrid):
    orb = cv2.ORB_create(ORB_FEATURES)
    return orb.detectAndCompute(image(g), None)


def _ratio_matches(d1, d2) -> list[tuple[int, int]]:
    out = []
    for m in cv2.BFMatcher(cv2.NORM_HAMMING).knnMatch(d1, d2, k=2):
        if len(m) == 2 and m[0].distance < (1.0 - MATCH_CONF) * m[1].distance:
            out.append((m[0].queryIdx, m[0].trainIdx))
    return out


def matches(d_mov, d_ref) -> list[tuple[int, int]]:
    """(moving index, reference index) pairs: the ratio test both ways, the union (each pair once)."""
    pairs = _ratio_matches(d_mov, d_ref)
    seen = set(pairs)
    for r, m in _ratio_matches(d_ref, d_mov):
        if (m, r) not in seen:
            seen.add((m, r))
            pairs.append((m, r))
    return pairs


def align(ref, mov, params=None) -> PairAnswer:
    """Map ``mov`` onto map ``ref`` (:class:`merger.team.orders.MapInput`) by m-explore's pipeline; ``params``
    is not used (the pipeline has its own constants, above)."""
    small = [f"{m.name} is {m.grid.height} × {m.grid.width} cells" for m in (ref, mov)
             if min(m.grid.height, m.grid.width) < MIN_SIDE]
    if small:
        return refused(f"features: {'; '.join(small)}: ORB finds features only {ORB_EDGE_PX} cells or more from "
                       f"every border, so each map needs at least {MIN_SIDE} cells a side",
                       sizes=[[m.grid.height, m.grid.width] for m in (ref, mov)])
    k_mov, d_mov = _features(mov.grid)
    k_ref, d_ref = _features(ref.grid)
    n_mov, n_ref = len(k_mov), len(k_ref)
    if d_mov is None or d_ref is None or n_mov < 2 or n_ref < 2:
        return refused(f"features: too few ORB features ({n_mov} and {n_ref})", features=[n_mov, n_ref])
    pairs = matches(d_mov, d_ref)
    ev = {"features": [n_mov, n_ref], "matches": len(pairs)}
    if len(pairs) < NUM_MATCHES_THRESH1:
        return refused(f"features: {len(pairs)} matches, fewer than {NUM_MATCHES_THRESH1}", **ev)
    src = np.float32([k_mov[m].pt for m, _ in pairs])
    dst = np.float32([k_ref[r].pt for _, r in pairs])
    cv2.setRNGSeed(0)
    a, inliers = cv2.estimateAffinePartial2D(src, dst, method=cv2.RANSAC, ransacReprojThreshold=RANSAC_REPROJ_PX)
    if a is None:
        return refused("features: RANSAC found no transform", **ev)
    n_in = int(inliers.sum())
    conf = n_in / (8 + 0.3 * len(pairs))
    theta, t = center_form(a, ref, mov)
    ev.update(inliers=n_in, confidence=conf, scale=float(math.hypot(a[0, 0], a[1, 0])))
    ok = conf >= CONFIDENCE_MIN
    return PairAnswer(ok, theta, t, conf, ev, "" if ok else
                      f"features: confidence {conf:.2f} = {n_in} inliers / (8 + 0.3 × {len(pairs)} matches) "
                      f"< {CONFIDENCE_MIN:g}")
