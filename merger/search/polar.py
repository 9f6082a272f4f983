"""Bounds of every whole-degree angle at once for one translation (docs/design/search.md, Lemma 6).

Lattice point k of the reference ROI reads, under θ, the moving cell containing c_m + R(−θ)k, whose
offset R(−θ)k has the polar coordinates (|k|, φ_k − θ) about c_m. With the moving frame cut into polar
cells of one lattice step radially and 1° in angle, and θ a whole degree, the lookup lies in polar cell
(ring of |k|, bin of φ_k − θ) = (ring, bin of φ_k shifted by θ): the same cell for every θ, shifted.
So with
* ``may_occ[ring, bin]`` — some occupied moving cell meets the polar cell's bounding box,
* ``sure_free[ring, bin]`` — every moving cell meeting that box is free, and the box lies inside the
  grid and the moving ROI's square,
agr̃(θ) ≤ Σ_k may_occ[ring_k, bin_k − θ] and dis(θ) ≥ Σ_k sure_free[ring_k, bin_k − θ] over the
reference ROI's occupied lattice points k: 360 bounds for |k| × 360 additions. The boxes are padded
by 1e-9 (m, cells): supersets, as the bounds need. A point within 1e-9 of a ring or bin edge counts in
both cells (OR for may_occ, AND for sure_free).
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .bounds import box_classes, inner_limit

PAD = 1e-9  # metres and degrees: float rounding of the lookups (~1e-15 relative) is far below it


@njit(cache=True, nogil=True)
def polar_tables(t, ring_w, n_rings):
    """(may_occ, not_sure_free) uint8 tables (n_rings, 360) of the moving map of ``t`` about c_m: each
    polar cell's Cartesian bounding box (padded) read in the summed-area table of (occupied << 32 | free)."""
    mh, mw = t.mstates.shape
    may_occ = np.zeros((n_rings, 360), np.uint8)
    not_free = np.ones((n_rings, 360), np.uint8)
    co = np.empty(361)
    si = np.empty(361)
    for g in range(361):
        co[g] = math.cos(math.radians(g))
        si[g] = math.sin(math.radians(g))
    inv = 1.0 / t.res_m
    u0 = (t.mcx - t.mox) * inv
    v0 = (t.mcy - t.moy) * inv
    lim = inner_limit(t.half)
    cls_sat = t.cls_sat
    for ring in range(n_rings):
        ra = max(ring * ring_w - PAD, 0.0)
        rb = (ring + 1) * ring_w + PAD
        for g in range(360):
            x_lo = min(ra * co[g], ra * co[g + 1], rb * co[g], rb * co[g + 1])
            x_hi = max(ra * co[g], ra * co[g + 1], rb * co[g], rb * co[g + 1])
            y_lo = min(ra * si[g], ra * si[g + 1], rb * si[g], rb * si[g + 1])
            y_hi = max(ra * si[g], ra * si[g + 1], rb * si[g], rb * si[g + 1])
            if g == 0 or g == 359:  # the bin touches the +x direction (0° or 360°)
                x_hi = max(x_hi, rb)
            elif g == 89 or g == 90:
                y_hi = max(y_hi, rb)
            elif g == 179 or g == 180:
                x_lo = min(x_lo, -rb)
            elif g == 269 or g == 270:
                y_lo = min(y_lo, -rb)
            # the cells the box meets (padded: the lookups' rounding)
            c0 = math.floor(u0 + x_lo * inv - PAD)
            c1 = math.floor(u0 + x_hi * inv + PAD)
            r0 = math.floor(v0 + y_lo * inv - PAD)
            r1 = math.floor(v0 + y_hi * inv + PAD)
            meets, inside, occ, free = box_classes(cls_sat, mh, mw, r0, r1, c0, c1)
            if not meets:
                continue  # outside the grid: unknown
            if occ > 0:
                may_occ[ring, g] = 1
            elif inside and free == (r1 - r0 + 1) * (c1 - c0 + 1):
                if max(abs(x_lo), abs(x_hi), abs(y_lo), abs(y_hi)) < lim:
                    not_free[ring, g] = 0
    return may_occ, not_free


@njit(cache=True, nogil=True)
def angle_bounds(kx, ky, may_occ, not_free, ring_w):
    """(agr_hi[360], dis_lo[360]) for the occupied lattice points (kx, ky) of the reference ROI."""
    n_rings = may_occ.shape[0]
    agr = np.zeros(360, np.int64)
    dis = np.zeros(360, np.int64)
    occ_row = np.empty(360, np.uint8)
    free_row = np.empty(360, np.uint8)
    for q in range(kx.size):
        rho = math.sqrt(kx[q] * kx[q] + ky[q] * ky[q])
        phi = math.degrees(math.atan2(ky[q], kx[q]))
        if phi < 0:
            phi += 360.0
        ra = int(math.floor((rho - PAD) / ring_w))
        rb = int(math.floor((rho + PAD) / ring_w))
        fa = int(math.floor(phi - PAD))
        fb = int(math.floor(phi + PAD))
        if ra >= n_rings:
            continue  # beyond every moving cell looked at: outside the square, unknown
        rb = min(rb, n_rings - 1)
        ra = max(ra, 0)
        if ra == rb and fa == fb:  # the usual case: one polar cell
            f = fa % 360
            mo = may_occ[ra]
            nf = not_free[ra]
            # under θ the lookup is in bin f − θ: θ ≤ f reads f − θ, θ > f reads f − θ + 360
            for th in range(f + 1):
                agr[th] += mo[f - th]
                dis[th] += 1 - nf[f - th]
            for th in range(f + 1, 360):
                agr[th] += mo[f - th + 360]
                dis[th] += 1 - nf[f - th + 360]
            continue
        for g in range(360):
            occ_row[g] = 0
            free_row[g] = 1
        for ring in (ra, rb):
            for f in (fa, fb):
                for th in range(360):
                    g = (f - th) % 360
                    occ_row[th] |= may_occ[ring, g]
                    if not_free[ring, g]:
                        free_row[th] = 0
        for th in range(360):
            agr[th] += occ_row[th]
            dis[th] += free_row[th] & (1 - occ_row[th])
    return agr, dis
