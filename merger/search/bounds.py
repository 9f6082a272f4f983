"""Upper bounds of the measure over a region of elements: angles × a box of translations (docs/design/search.md §4).

A region is a range of angle indices ``lo..hi`` of the search's angle array × a box ``(a0, a1, b0, b1)``
of translation indices (0..2K). Its bound comes from bounds on the counts (agr̃ ≤ agr_hi, dis ≥ dis_lo)
turned into a bound on the value by the measure (:func:`merger.measures.upper_of`, Lemma 4):

* :func:`region_bound` — the reference side (Lemma 3): the reference's occupied cells (pooled in blocks
  of 2^L cells) looked up in the moving map's summed-area table over the disc every lookup of the
  region can reach;
* :func:`moving_bound` — the moving side at one angle (Lemma 3b): each occupied lattice point against the
  rectangle of reference cells it reads over the box;
* :func:`region_upper` — both, as the branch and bound combines them (compiled);
* :func:`merger.search.polar.angle_bounds` — every whole degree at once, rotation only (Lemma 6).

tests/merger/search/test_bounds.py checks each against the brute-force maximum over its region.
"""

from __future__ import annotations

import math

from ..jit import njit
from ..measures import upper_of

EPS_CELLS = 1e-6  # margin of the bound's discs (cells): covers the bound's own float rounding
SMALL_BOX = 4  # boxes narrower than this get exact per-translation weights (non-plain ROIs)


@njit(cache=True, nogil=True, inline=True)
def sat_sum(sat, r0, r1, c0, c1):
    """Sum of the cells [r0, r1] × [c0, c1] (inclusive) of a summed-area table with a zero border."""
    return sat[r1 + 1, c1 + 1] - sat[r0, c1 + 1] - sat[r1 + 1, c0] + sat[r0, c0]


@njit(cache=True, nogil=True, inline=True)
def box_classes(sat, h, w, r0, r1, c0, c1):
    """The cells [r0, r1] × [c0, c1] of an h × w grid in its (occupied << 32 | free) summed-area table:
    (meets the grid, lies inside it, occupied count, free count) of the part inside the grid."""
    if c1 < 0 or r1 < 0 or c0 >= w or r0 >= h:
        return False, False, 0, 0
    inside = c0 >= 0 and r0 >= 0 and c1 < w and r1 < h
    both = sat_sum(sat, int(max(r0, 0)), int(min(r1, h - 1)), int(max(c0, 0)), int(min(c1, w - 1)))
    return True, inside, both >> 32, both & 0xFFFFFFFF


@njit(cache=True, nogil=True, inline=True)
def inner_limit(half):
    """Lookups of an offset whose larger coordinate stays below this are inside the ROI's square of
    half-side ``half`` (the margin covers the lookups' rounding)."""
    return half * (1.0 - 1e-12) - 1e-9


@njit(cache=True, nogil=True)
def region_bound(t, th_mid, half_rad, box, level):
    """(agr_hi, dis_lo) over the angles within ``half_rad`` of ``th_mid`` (degrees) and the box ``box`` =
    (a0, a1, b0, b1) of translation indices, from the reference's occupied cells pooled in blocks of
    2^``level`` cells (Lemma 3; the tables: :class:`merger.search.prepared.Tables`)."""
    n = t.n
    res, inv = t.res, 1.0 / t.res_m  # lookups in moving cells: u = u0 + R(−θm)k / res_m
    dev_r, dev_c = t.axes_r[1], t.axes_c[1]
    a0, a1, b0, b1 = box[0], box[1], box[2], box[3]
    mh, mw = t.mstates.shape
    th = math.radians(-th_mid)
    co, si = math.cos(th), math.sin(th)
    u0 = (t.mcx - t.mox) * inv
    v0 = (t.mcy - t.moy) * inv
    cxo = co * inv
    sxo = si * inv
    chord = 2.0 * math.sin(half_rad / 2.0) if half_rad > 0 else 0.0
    hl = ((1 << level) - 1) / 2.0
    ha = (a1 - a0) / 2.0 + dev_c + hl
    hb = (b1 - b0) / 2.0 + dev_r + hl
    rho_t = res * math.sqrt(ha * ha + hb * hb)
    acr = (a0 + a1) / 2.0 * res  # the box center's shift of every block's lattice position
    bcr = (b0 + b1) / 2.0 * res
    shift = math.sqrt(acr * acr + bcr * bcr)
    size = 1 << level
    # rows (columns) inside every ROI of the box: base + b1 + dev .. base + b0 + n − 1 − dev (Lemma 1)
    ar0, ar1 = t.axes_r[0] + b1 + dev_r, t.axes_r[0] + b0 + n - 1 - dev_r
    ac0, ac1 = t.axes_c[0] + a1 + dev_c, t.axes_c[0] + a0 + n - 1 - dev_c
    lim = inner_limit(t.half)
    blk, blkf, cls_sat = t.blk, t.blkf, t.cls_sat  # locals: fields of t are read again in every iteration
    wr0, wc0, ilo, ihi, jlo, jhi, rlo, clo = t.wr0, t.wc0, t.ilo, t.ihi, t.jlo, t.jhi, t.rlo, t.clo
    agr = 0
    dis = 0
    # small boxes of a ROI that is not a plain block: each cell weighted by its reads at these translations
    exact_w = level == 0 and (dev_r > 0 or dev_c > 0) and b1 - b0 < SMALL_BOX and a1 - a0 < SMALL_BOX
    for q in range(t.lvl_start[level], t.lvl_start[level + 1]):
        rr = blk[q, 0]  # first row / column of the block
        cc = blk[q, 1]
        w_hi = blk[q, 3]
        w_lo = 1
        rho = rho_t
        if exact_w:
            w_hi, w_lo, kx, ky, rho, knorm = _exact_weights(wr0, wc0, ilo, ihi, jlo, jhi, n, res, q, rr - rlo,
                                                            cc - clo, box)
            if w_hi == 0:
                continue
        else:
            kx = blkf[q, 0] - acr  # the block's center on the lattice at the box center
            ky = blkf[q, 1] - bcr
            knorm = blkf[q, 2] + shift  # |k| ≤ |k at translation 0| + |shift|
        if chord > 0:
            rho += chord * knorm
        rc = rho * inv + EPS_CELLS
        u = u0 + (cxo * kx - sxo * ky)
        v = v0 + (sxo * kx + cxo * ky)
        r0, r1 = math.floor(v - rc), math.floor(v + rc)
        c0, c1 = math.floor(u - rc), math.floor(u + rc)
        meets, inside, occ, free = box_classes(cls_sat, mh, mw, r0, r1, c0, c1)
        if not meets:
            continue  # every lookup outside the moving map: unknown
        if occ > 0:
            agr += w_hi
            continue
        if not inside or free != (r1 - r0 + 1) * (c1 - c0 + 1):
            continue
        px = co * kx - si * ky
        py = si * kx + co * ky
        if max(abs(px), abs(py)) + rho >= lim:
            continue
        # surely free at every lookup: dis for each translation, which reads each of the cells at least once
        if exact_w:
            dis += w_lo
        elif blk[q, 4] and rr >= ar0 and rr + size - 1 <= ar1 and cc >= ac0 and cc + size - 1 <= ac1:
            dis += blk[q, 2]
    return agr, dis


@njit(cache=True, nogil=True, inline=True)
def _exact_weights(wr0, wc0, ilo, ihi, jlo, jhi, n, res, q, r, c, box):
    """For cell q of level 0 (row r, column c of the tables) and a small box: (most reads at one
    translation, 1 when every translation reads it, the center (m) and half-diagonal (m) of the lattice
    points reading it, and |center|). Inlined, its arrays given: a call per cell made centers on cell
    centres 1.6–2x slower (measured)."""
    wr_hi, wr_lo, i0, i1 = _axis_reads(wr0, ilo, ihi, box[2], box[3], q, r, n)
    wc_hi, wc_lo, j0, j1 = _axis_reads(wc0, jlo, jhi, box[0], box[1], q, c, n)
    w_hi = wr_hi * wc_hi
    w_lo = 1 if wr_lo >= 1 and wc_lo >= 1 else 0
    m = (n - 1) / 2.0
    kx = ((j0 + j1) / 2.0 - m) * res
    ky = ((i0 + i1) / 2.0 - m) * res
    hj = (j1 - j0) / 2.0
    hi_ = (i1 - i0) / 2.0
    return w_hi, w_lo, kx, ky, res * math.sqrt(hj * hj + hi_ * hi_), math.sqrt(kx * kx + ky * ky)


@njit(cache=True, nogil=True, inline=True)
def _axis_reads(w0, lo_tab, hi_tab, t0, t1, q, r, n):
    """Along one axis, over the translations t0..t1: the most and the fewest lattice lines reading cell q
    (table row r) at one translation, and the first and last of those lines."""
    w_hi, w_lo, i0, i1 = 0, 2, n, -1
    for b in range(t0, t1 + 1):
        x = w0[b, q]
        w_hi = max(w_hi, x)
        w_lo = min(w_lo, x)
        if x > 0:
            i0 = min(i0, lo_tab[b, r])
            i1 = max(i1, hi_tab[b, r] - 1)
    return w_hi, w_lo, i0, i1


@njit(cache=True, nogil=True)
def moving_bound(t, pts, box):
    """(agr_hi, dis_lo) from the moving side at one angle over the box ``box`` = (a0, a1, b0, b1)
    (Lemma 3b): each occupied lattice point (``pts``, indices i·n + j) reads, at the box's translations,
    reference cells inside the rectangle rows[b0, i]..rows[b1, i] × cols[a0, j]..cols[a1, j] (the tables
    are monotone, Lemma 1). It agrees at most once, when that rectangle holds an occupied cell; it
    disagrees at every translation when the whole rectangle is known and free. ``t.ref_sat``: the
    reference's (occupied << 32 | free) summed-area table over every cell a translation reads."""
    a0, a1, b0, b1 = box[0], box[1], box[2], box[3]
    n = t.n
    r_lo, c_lo = t.rlo, t.clo
    r_hi, c_hi = r_lo + t.ref_sat.shape[0] - 2, c_lo + t.ref_sat.shape[1] - 2
    agr = 0
    dis = 0
    h, w = t.ref.shape
    rows, cols, ref_sat, dev_r, dev_c = t.rows, t.cols, t.ref_sat, t.axes_r[1], t.axes_c[1]
    for x in range(pts.size):
        p = pts[x]
        i = p // n
        j = p - i * n
        r0, r1, known_r = _span(rows, b0, b1, i, r_lo, r_hi, h, dev_r)
        if r0 < 0:
            continue  # read nowhere in the box
        c0, c1, known_c = _span(cols, a0, a1, j, c_lo, c_hi, w, dev_c)
        if c0 < 0:
            continue
        both = sat_sum(ref_sat, r0 - r_lo, r1 - r_lo, c0 - c_lo, c1 - c_lo)
        if (both >> 32) > 0:
            agr += 1
        elif known_r and known_c and (both & 0xFFFFFFFF) == (r1 - r0 + 1) * (c1 - c0 + 1):
            dis += 1
    return agr, dis


@njit(cache=True, nogil=True, inline=True)
def _span(tab, lo, hi, i, first, last, size, dev):
    """The reference rows (columns) lattice line ``i`` reads at the translations lo..hi — tab[lo, i] ..
    tab[hi, i], the tables being non-decreasing (Lemma 1), −1 outside the grid — as (start, end, whether
    every translation reads inside the grid); (−1, −1, False) when none does. An end outside is replaced
    by the first (last) readable row. Both ends outside: on one side of the grid (read nowhere), or on
    opposite sides of a grid no taller than the box (every row read)."""
    x0, x1 = tab[lo, i], tab[hi, i]
    if x0 >= 0 or x1 >= 0:
        return (x0 if x0 >= 0 else first), (x1 if x1 >= 0 else last), x0 >= 0 and x1 >= 0
    if hi - lo + 2 * dev > size:  # the box can span the grid: from below it to above it
        for x in range(lo + 1, hi):
            if tab[x, i] >= 0:
                return first, last, False
    return -1, -1, False


@njit(cache=True, nogil=True, inline=True)
def block_level(t, box, half_rad):
    """The block level of a region's reference-side bound: blocks no wider than the region's own blur."""
    rmax = t.half * math.sqrt(2.0)
    blur = ((box[1] - box[0]) + (box[3] - box[2])) / 4.0 + 2.0 * math.sin(half_rad / 2.0) * rmax / t.res / 2.0
    level = 0
    while level + 2 < t.lvl_start.size and (1 << (level + 1)) <= blur:
        level += 1
    return level


@njit(cache=True, nogil=True, inline=True)
def sum_ranges(t, asum, lo, hi, box):
    """The measure's count tables over a region: (sx_lo, sx_hi) per translation of the box, (sy_lo, sy_hi)
    per angle lo..hi (empty ranges when the measure needs none)."""
    sx_lo, sx_hi, sy_lo, sy_hi = 1 << 40, -1, 1 << 40, -1
    if t.sums:
        tsum, side = t.tsum, t.side
        for b in range(box[2], box[3] + 1):
            for a in range(box[0], box[1] + 1):
                x = tsum[b * side + a]
                sx_lo = min(sx_lo, x)
                sx_hi = max(sx_hi, x)
        for x in range(lo, hi + 1):
            sy_lo = min(sy_lo, asum[x])
            sy_hi = max(sy_hi, asum[x])
    return sx_lo, sx_hi, sy_lo, sy_hi


@njit(cache=True, nogil=True)
def region_upper(t, angles, asum, lo, hi, box, pts, stop):
    """The measure's upper bound over the region angles[lo..hi] × ``box``: at one angle with a window,
    the moving side first (``pts``: that angle's occupied lattice points) — returned alone when it is
    below ``stop`` — then the reference side, the two combined (Lemma 3b)."""
    sx_lo, sx_hi, sy_lo, sy_hi = sum_ranges(t, asum, lo, hi, box)
    m_agr, m_dis = -1, 0
    if t.k > 0 and lo == hi:
        m_agr, m_dis = moving_bound(t, pts, box)
        ub = upper_of(t.code, t.floor, m_agr, m_dis, sx_lo, sx_hi, sy_lo, sy_hi, t.n * t.n)
        if ub < stop:  # the reference side would only lower it (Lemma 4b)
            return ub
    th_mid = (angles[lo] + angles[hi]) / 2.0
    half_rad = math.radians((angles[hi] - angles[lo]) / 2.0)
    agr_hi, dis_lo = region_bound(t, th_mid, half_rad, box, block_level(t, box, half_rad))
    if m_agr >= 0:  # both sides: disjoint dis terms (Lemma 3b)
        agr_hi = min(agr_hi, m_agr)
        dis_lo += m_dis
    return upper_of(t.code, t.floor, agr_hi, dis_lo, sx_lo, sx_hi, sy_lo, sy_hi, t.n * t.n)
