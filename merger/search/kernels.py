"""Compiled kernels of the search: exact counts, region bounds and the branch and bound.

(Longer than ~400 lines: the kernels share one set of arrays and are read together; the branch and
bound is one compiled function so that its loop never returns to Python.)

Everything here works on the arrays of :class:`merger.search.prepared.Prepared` (the lattice tables of
:mod:`merger.search.lattice`) and is compiled with ``@njit(cache=True, nogil=True)`` (no fastmath): the
kernels release the GIL, so the searches of a merge cycle run side by side on threads.

* :func:`fill_moving` — the moving ROI under one angle (dense states and its occupied points).
* :func:`exact_counts` — agr̃, dis (and free/free) at one (θ, t): the moving ROI's occupied points
  read the reference through the tables; the reference's occupied cells read the moving ROI through
  the tables' preimages (Lemma 2).
* :func:`region_bound` — an upper bound of the measure over a sector of angles × a box of
  translations, from the reference's occupied cells (pooled in blocks of 2^L cells) looked up in
  summed-area tables of the moving map over the disc every lookup of the region can reach (Lemma 3).
* :func:`moving_bound` — at one angle, the same from the moving side: each occupied lattice point against
  the rectangle of reference cells it reads over the box (Lemma 3b); :func:`moving_points_all` gives
  those points for every coarse angle at once (kept per moving map by the engine).
* :func:`branch_and_bound` — best-first over (sector, box) regions, angles split before boxes; a region
  is dropped when its bound key cannot come before the incumbent in the reference's order (Lemma 5).
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .lattice import moving_states, state_at
from .measures import BIRK_CARPIN, NCC, upper_of, value_of

EPS_CELLS = 1e-6  # margin of the bound's discs (cells): covers the bound's own float rounding
LEVELS = 5  # reference blocks of 1, 2, 4, 8, 16 cells
SMALL_BOX = 4  # boxes narrower than this get exact per-translation weights (non-plain ROIs)


@njit(cache=True, nogil=True)
def fill_moving(mstates, res_m, ox, oy, cx, cy, n, res, r00, r01, r10, r11, dense, pocc):
    """The moving ROI under one angle into ``dense`` (n·n) and its occupied points into ``pocc``;
    returns (number of occupied points, number of free points)."""
    n_occ, n_free = moving_states(mstates, res_m, ox, oy, cx, cy, n, res, r00, r01, r10, r11, dense)
    k = 0
    for p in range(n * n):
        if dense[p] == 2:
            pocc[k] = p
            k += 1
    return n_occ, n_free


@njit(cache=True, nogil=True)
def sparse_moving(mstates, res_m, ox, oy, cx, cy, n, res, r00, r01, r10, r11, occ_x, occ_y, mark, gen, pocc):
    """The occupied lattice points of the moving ROI under one angle into ``pocc``, without the dense
    ROI: each occupied moving cell (centre (occ_x, occ_y) about c_m) is read only by lattice points
    within 0.7072 cell of R(θ)(its centre) (the rotated cell's half-diagonal); those candidates are
    read with :func:`merger.search.lattice.state_at`. ``mark``/``gen``: candidates seen. Returns their
    number."""
    m = (n - 1) / 2.0
    half = n * res / 2.0
    reach = 0.7072 * res_m / res + 1e-6
    count = 0
    for q in range(occ_x.size):
        # R(θ) is the transpose of R(−θ)
        jc = (r00 * occ_x[q] + r10 * occ_y[q]) / res + m
        ic = (r01 * occ_x[q] + r11 * occ_y[q]) / res + m
        i0 = max(int(math.ceil(ic - reach)), 0)
        i1 = min(int(math.floor(ic + reach)), n - 1)
        j0 = max(int(math.ceil(jc - reach)), 0)
        j1 = min(int(math.floor(jc + reach)), n - 1)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                p = i * n + j
                if mark[p] == gen:
                    continue
                mark[p] = gen
                if state_at(mstates, res_m, ox, oy, cx, cy, m, half, res, r00, r01, r10, r11, i, j) == 2:
                    pocc[count] = p
                    count += 1
    return count


@njit(cache=True, nogil=True)
def moving_points_all(mstates, res_m, ox, oy, cx, cy, n, res, rot, occ_x, occ_y):
    """:func:`sparse_moving` at every angle of ``rot`` (rows of R(−θ) entries): the occupied lattice
    points of angle x are ``buf[start[x]:start[x] + cnt[x]]``."""
    n_ang = rot.shape[0]
    start = np.empty(n_ang, np.int64)
    cnt = np.empty(n_ang, np.int64)
    mark = np.zeros(n * n, np.int32)
    tmp = np.empty(n * n, np.int32)
    buf = np.empty(max(1024, 2 * occ_x.size * n_ang), np.int32)
    used = 0
    for x in range(n_ang):
        c = sparse_moving(mstates, res_m, ox, oy, cx, cy, n, res, rot[x, 0], rot[x, 1], rot[x, 2], rot[x, 3],
                          occ_x, occ_y, mark, x + 1, tmp)
        buf = _append(buf, used, tmp, c)
        start[x] = used
        cnt[x] = c
        used += c
    return start, cnt, buf[:used].copy()


@njit(cache=True, nogil=True)
def _append(buf, used, src, c):
    """``src[:c]`` written at ``buf[used:]``, the buffer grown (doubled) when it is too small."""
    if used + c > buf.size:
        grown = np.empty(max(2 * buf.size, used + c), np.int32)
        grown[:used] = buf[:used]
        buf = grown
    buf[used:used + c] = src[:c]
    return buf


@njit(cache=True, nogil=True)
def _moving_occupied_term(pocc, n_occ, ref, cols, rows, ai, bi, n):
    """(agr, dis from the moving side): each occupied lattice point against the reference cell it reads."""
    agr = 0
    dis = 0
    for t in range(n_occ):
        p = pocc[t]
        i = p // n
        j = p - i * n
        r = rows[bi, i]
        c = cols[ai, j]
        if r >= 0 and c >= 0:
            s = ref[r, c]
            if s == 2:
                agr += 1
            elif s == 1:
                dis += 1
    return agr, dis


@njit(cache=True, nogil=True)
def exact_counts_sparse(pocc, n_occ, ref, cols, rows, ai, bi, qr, qc, rlo, clo, ilo, ihi, jlo, jhi, n,
                        mstates, res_m, ox, oy, cx, cy, res, r00, r01, r10, r11):
    """(agr, dis) as :func:`exact_counts`, the moving ROI read point by point (no dense ROI)."""
    agr, dis = _moving_occupied_term(pocc, n_occ, ref, cols, rows, ai, bi, n)
    m = (n - 1) / 2.0
    half = n * res / 2.0
    for q in range(qr.size):
        r = qr[q] - rlo
        c = qc[q] - clo
        for i in range(ilo[bi, r], ihi[bi, r]):
            for j in range(jlo[ai, c], jhi[ai, c]):
                if state_at(mstates, res_m, ox, oy, cx, cy, m, half, res, r00, r01, r10, r11, i, j) == 1:
                    dis += 1
    return agr, dis


@njit(cache=True, nogil=True)
def exact_counts(dense, pocc, n_occ, ref, cols, rows, ai, bi, qr, qc, rlo, clo, ilo, ihi, jlo, jhi, n,
                 need_ff):
    """(agr, dis, ff) of the moving ROI ``dense`` against the reference ROI at translation (ai, bi)."""
    agr, dis = _moving_occupied_term(pocc, n_occ, ref, cols, rows, ai, bi, n)
    for q in range(qr.size):  # reference occupied: the lattice points that read it, against moving free
        r = qr[q] - rlo
        c = qc[q] - clo
        for i in range(ilo[bi, r], ihi[bi, r]):
            for j in range(jlo[ai, c], jhi[ai, c]):
                if dense[i * n + j] == 1:
                    dis += 1
    ff = 0
    if need_ff:
        for i in range(n):
            r = rows[bi, i]
            if r < 0:
                continue
            for j in range(n):
                c = cols[ai, j]
                if c >= 0 and ref[r, c] == 1 and dense[i * n + j] == 1:
                    ff += 1
    return agr, dis, ff


@njit(cache=True, nogil=True)
def _sat(t, r0, r1, c0, c1):
    """Sum of the cells [r0, r1] × [c0, c1] (inclusive) of a summed-area table with a zero border."""
    return t[r1 + 1, c1 + 1] - t[r0, c1 + 1] - t[r1 + 1, c0] + t[r0, c0]


@njit(cache=True, nogil=True)
def region_bound(geo, axes_r, axes_c, blk, blkf, lvl_start, wr0, wc0, ilo, ihi, jlo, jhi, cls_sat, mh, mw,
                 th_mid, half_rad, box, level):
    """(agr_hi, dis_lo) over the angles within ``half_rad`` of ``th_mid`` (degrees) and the box
    ``box`` = (a0, a1, b0, b1) of translation indices (Lemma 3).

    geo = (n, res, res_m, mox, moy, mcx, mcy, half): the lattice and the moving map's geometry.
    axes_r / axes_c = (base, dev, mult, lo) per axis: the reference row (column) read by lattice row i at
    translation index b is base + b + i ± dev, at most ``mult`` lattice rows read one cell, ``lo`` is
    the first reference row of the tables. cls_sat: summed-area table of the moving map's
    (occupied << 32 | free) indicators. blk: (row, col, count, weighted count, never skipped) of the
    reference's occupied cells pooled in blocks (level l: blocks of 2^l cells, rows
    ``lvl_start[l]:lvl_start[l+1]``; see :meth:`merger.search.prepared.Prepared._blocks`)."""
    n = int(geo[0])
    res, res_m, mox, moy, mcx, mcy, half = geo[1], geo[2], geo[3], geo[4], geo[5], geo[6], geo[7]
    base_r, dev_r, lo_r = axes_r[0], axes_r[1], axes_r[3]
    base_c, dev_c, lo_c = axes_c[0], axes_c[1], axes_c[3]
    a0, a1, b0, b1 = box[0], box[1], box[2], box[3]
    m = (n - 1) / 2.0
    t = math.radians(-th_mid)
    co, si = math.cos(t), math.sin(t)
    inv = 1.0 / res_m  # lookups in moving cells: u = u0 + R(−θm)k / res_m (the margin covers the rounding)
    u0 = (mcx - mox) * inv
    v0 = (mcy - moy) * inv
    cxo = co * inv
    sxo = si * inv
    chord = 2.0 * math.sin(half_rad / 2.0) if half_rad > 0 else 0.0
    hl = ((1 << level) - 1) / 2.0
    ha = (a1 - a0) / 2.0 + dev_c + hl
    hb = (b1 - b0) / 2.0 + dev_r + hl
    rho_t = res * math.sqrt(ha * ha + hb * hb)
    ac = (a0 + a1) / 2.0
    bc = (b0 + b1) / 2.0
    acr = ac * res  # the box center's shift of every block's lattice position
    bcr = bc * res
    shift = math.sqrt(acr * acr + bcr * bcr)
    size = 1 << level
    # rows (columns) inside every ROI of the box: base + b1 + dev .. base + b0 + n − 1 − dev (Lemma 1)
    ar0, ar1 = base_r + b1 + dev_r, base_r + b0 + n - 1 - dev_r
    ac0, ac1 = base_c + a1 + dev_c, base_c + a0 + n - 1 - dev_c
    agr = 0
    dis = 0
    # small boxes of a ROI that is not a plain block: each cell weighted by its reads at these translations
    exact_w = level == 0 and (dev_r > 0 or dev_c > 0) and b1 - b0 < SMALL_BOX and a1 - a0 < SMALL_BOX
    for q in range(lvl_start[level], lvl_start[level + 1]):
        rr = blk[q, 0]  # first row / column of the block
        cc = blk[q, 1]
        cnt = blk[q, 2]
        w_hi = blk[q, 3]
        w_lo = 1
        rho_q = rho_t
        if exact_w:
            # the lattice rows and columns that read this cell at the box's translations, exactly (rows and
            # columns written out: a shared helper made centers on cell centres 1.6–2x slower, measured)
            i0, i1, j0, j1 = n, -1, n, -1
            wr_hi, wr_lo, wc_hi, wc_lo = 0, 2, 0, 2
            for b in range(b0, b1 + 1):
                x = wr0[b, q]
                wr_hi = max(wr_hi, x)
                wr_lo = min(wr_lo, x)
                if x > 0:
                    i0 = min(i0, ilo[b, rr - lo_r])
                    i1 = max(i1, ihi[b, rr - lo_r] - 1)
            for a in range(a0, a1 + 1):
                x = wc0[a, q]
                wc_hi = max(wc_hi, x)
                wc_lo = min(wc_lo, x)
                if x > 0:
                    j0 = min(j0, jlo[a, cc - lo_c])
                    j1 = max(j1, jhi[a, cc - lo_c] - 1)
            w_hi = wr_hi * wc_hi
            w_lo = 1 if wr_lo >= 1 and wc_lo >= 1 else 0
            if w_hi == 0:
                continue
            kx = ((j0 + j1) / 2.0 - m) * res
            ky = ((i0 + i1) / 2.0 - m) * res
            hj = (j1 - j0) / 2.0
            hi_ = (i1 - i0) / 2.0
            rho_q = res * math.sqrt(hj * hj + hi_ * hi_)
            knorm = math.sqrt(kx * kx + ky * ky)
        else:
            kx = blkf[q, 0] - acr  # the block's center on the lattice at the box center
            ky = blkf[q, 1] - bcr
            knorm = blkf[q, 2] + shift  # |k| ≤ |k at translation 0| + |shift|
        rho = rho_q
        if chord > 0:
            rho += chord * knorm
        rc = rho * inv + EPS_CELLS
        u = u0 + (cxo * kx - sxo * ky)
        v = v0 + (sxo * kx + cxo * ky)
        c0 = math.floor(u - rc)
        c1 = math.floor(u + rc)
        r0 = math.floor(v - rc)
        r1 = math.floor(v + rc)
        if c1 < 0 or r1 < 0 or c0 >= mw or r0 >= mh:
            continue  # every lookup outside the moving map: unknown
        inside = c0 >= 0 and r0 >= 0 and c1 < mw and r1 < mh
        cr0, cr1 = max(r0, 0), min(r1, mh - 1)
        cc0, cc1 = max(c0, 0), min(c1, mw - 1)
        both = _sat(cls_sat, int(cr0), int(cr1), int(cc0), int(cc1))  # occupied << 32 | free
        if (both >> 32) > 0:
            agr += w_hi
            continue
        if not inside:
            continue
        area = (r1 - r0 + 1) * (c1 - c0 + 1)
        if (both & 0xFFFFFFFF) != area:  # inside: the clipped square is the square
            continue
        px = co * kx - si * ky
        py = si * kx + co * ky
        if max(abs(px), abs(py)) + rho >= half * (1.0 - 1e-12) - 1e-9:
            continue
        # surely free at every lookup: dis for each translation, which reads each of the cells at least once
        if exact_w:
            dis += w_lo
        elif blk[q, 4] and rr >= ar0 and rr + size - 1 <= ar1 and cc >= ac0 and cc + size - 1 <= ac1:
            dis += cnt
    return agr, dis


@njit(cache=True, nogil=True)
def moving_bound(pts, start, cnt, n, rows, cols, ref_sat, r_lo, r_hi, c_lo, c_hi, box):
    """(agr_hi, dis_lo) from the moving side at one angle over the box ``box`` = (a0, a1, b0, b1)
    (Lemma 3b): each occupied lattice point (``pts[start:start+cnt]``, indices i·n + j) reads, at the
    box's translations, reference cells inside the rectangle rows[b0, i]..rows[b1, i] ×
    cols[a0, j]..cols[a1, j] (the tables are monotone, Lemma 1). It agrees at most once, when that
    rectangle holds an occupied cell; it disagrees at every translation when the whole rectangle is
    known and free. ref_sat: summed-area table of the reference's (occupied << 32 | free) indicators
    over rows r_lo..r_hi, columns c_lo..c_hi (every cell a translation reads)."""
    a0, a1, b0, b1 = box[0], box[1], box[2], box[3]
    agr = 0
    dis = 0
    for t in range(start, start + cnt):
        p = pts[t]
        i = p // n
        j = p - i * n
        ra = rows[b0, i]
        rb = rows[b1, i]
        ca = cols[a0, j]
        cb = cols[a1, j]
        if (ra < 0 and rb < 0) or (ca < 0 and cb < 0):
            continue  # read nowhere in the box (a −1 at one end only: the part beyond that end is outside)
        r0 = ra if ra >= 0 else r_lo
        r1 = rb if rb >= 0 else r_hi
        c0 = ca if ca >= 0 else c_lo
        c1 = cb if cb >= 0 else c_hi
        both = _sat(ref_sat, r0 - r_lo, r1 - r_lo, c0 - c_lo, c1 - c_lo)
        if (both >> 32) > 0:
            agr += 1
        elif ra >= 0 and rb >= 0 and ca >= 0 and cb >= 0 and (both & 0xFFFFFFFF) == (r1 - r0 + 1) * (c1 - c0 + 1):
            dis += 1
    return agr, dis


@njit(cache=True, nogil=True)
def _heap_push(hv, hi, size, v, i):
    k = size
    hv[k] = v
    hi[k] = i
    while k > 0:
        p = (k - 1) >> 1
        if hv[p] >= hv[k]:
            break
        hv[p], hv[k] = hv[k], hv[p]
        hi[p], hi[k] = hi[k], hi[p]
        k = p
    return size + 1


@njit(cache=True, nogil=True)
def _heap_pop(hv, hi, size):
    v, i = hv[0], hi[0]
    size -= 1
    hv[0] = hv[size]
    hi[0] = hi[size]
    k = 0
    while True:
        l = 2 * k + 1
        if l >= size:
            break
        c = l
        if l + 1 < size and hv[l + 1] > hv[l]:
            c = l + 1
        if hv[k] >= hv[c]:
            break
        hv[k], hv[c] = hv[c], hv[k]
        hi[k], hi[c] = hi[c], hi[k]
        k = c
    return v, i, size


@njit(cache=True, nogil=True)
def _keep(fr_nodes, fr_vals, n_fr, lo, hi, a0, a1, b0, b1, v):
    """Append a region (angles lo..hi, box a0..a1 × b0..b1) and its bound to the frontier arrays."""
    if n_fr >= fr_nodes.shape[0]:
        grown = np.empty((2 * fr_nodes.shape[0] + 256, 6), np.int64)
        grown[:n_fr] = fr_nodes[:n_fr]
        fr_nodes = grown
        grown_v = np.empty(grown.shape[0], np.float64)
        grown_v[:n_fr] = fr_vals[:n_fr]
        fr_vals = grown_v
    fr_nodes[n_fr, 0], fr_nodes[n_fr, 1] = lo, hi
    fr_nodes[n_fr, 2], fr_nodes[n_fr, 3], fr_nodes[n_fr, 4], fr_nodes[n_fr, 5] = a0, a1, b0, b1
    fr_vals[n_fr] = v
    return fr_nodes, fr_vals


@njit(cache=True, nogil=True)
def _dropped(env, lo, hi, a0, a1, b0, b1, v, inc0, keep, fr_nodes, fr_vals, n_fr):
    """A region dropped with bound ``v`` (below the incumbent ``inc0``): the envelope of its angles
    raised to ``v``, and the region kept in the frontier when ``v`` ≥ inc0 − ``keep`` (Lemma 5b)."""
    for x in range(lo, hi + 1):
        env[x] = max(env[x], v)
    if keep >= 0 and v >= inc0 - keep:
        fr_nodes, fr_vals = _keep(fr_nodes, fr_vals, n_fr, lo, hi, a0, a1, b0, b1, v)
        n_fr += 1
    return fr_nodes, fr_vals, n_fr


@njit(cache=True, nogil=True)
def _before(v, p, s, iv, ip, is_):
    """Whether the key (v, −p, −s) comes before (is greater than) (iv, −ip, −is)."""
    if v != iv:
        return v > iv
    if p != ip:
        return p < ip
    return s < is_


@njit(cache=True, nogil=True)
def branch_and_bound(ctx_f, ctx_i, ref, cols, rows, qr, qc, ilo, ihi, jlo, jhi,
                     axes_r, axes_c, blk, blkf, lvl_start, wr0, wc0, mstates, cls_sat,
                     angles, rot, amask, tmask, rank, tsum, asum, excl_a, excl_t,
                     slots_dense, slots_pocc, slot_angle, slot_counts, inc, env, init_nodes, init_vals,
                     occ_x, occ_y, mark, gen, ref_sat, pre_start, pre_cnt, pre_buf, keep):
    """Best-first branch and bound over (angle sector, translation box) regions (Lemma 5).

    ctx_f = (res, res_m, mox, moy, mcx, mcy, half); ctx_i = (n, k, code, mode, need_ff, sector0, budget, floor).
    angles/rot: the angles searched (degrees) and their R(−θ) entries; amask/tmask: the angles and
    translations allowed; rank: the tie rank of each translation index b·(2k+1) + a; tsum/asum: the
    measure's count tables per translation / per angle; excl_a × excl_t: elements excluded.
    mode 0 orders elements by (value, −rank, −angle), mode 1 by (value, −angle, −rank).
    inc = [value, p, s, angle, a, b, agr, dis, ff]: the incumbent, updated in place; env: per angle,
    the largest bound or exact value seen (an upper envelope of the best value over translations).
    ctx_i[6]: a budget of regions bounded (0: none). ``keep`` ≥ 0: the regions dropped, and the elements
    evaluated, with a bound (value) at least the incumbent's value − keep at that moment are returned
    (the frontier a later search for placements within ``keep`` of the answer can start from). Returns
    (regions bounded, exact evaluations, whether the search completed: the incumbent is then the answer,
    frontier regions (m, 6), their bounds (m))."""
    res, res_m, mox, moy, mcx, mcy, half = ctx_f[0], ctx_f[1], ctx_f[2], ctx_f[3], ctx_f[4], ctx_f[5], ctx_f[6]
    n, k, code, mode, need_ff, sector0 = ctx_i[0], ctx_i[1], ctx_i[2], ctx_i[3], ctx_i[4], ctx_i[5]
    budget = ctx_i[6]  # the most regions bounded (0: no limit); beyond it the incumbent is returned as is
    floor = ctx_i[7]  # the support floor (measures.value_of)
    side = 2 * k + 1
    n_ang = angles.size
    mh, mw = mstates.shape
    geo = np.array([n, res, res_m, mox, moy, mcx, mcy, half])
    rmax = half * math.sqrt(2.0)
    n_slots = slot_angle.size
    cap = max(4096, 2 * init_nodes.shape[0])
    nodes = np.empty((cap, 7), np.int64)  # angle lo, hi, a0, a1, b0, b1, depth
    hv = np.empty(cap, np.float64)
    hi_ = np.empty(cap, np.int64)
    bounds_ = np.full(cap, np.inf)  # each region's own bound
    size = 0
    n_nodes = 0
    n_bounds = 0
    n_exact = 0
    box = np.empty(4, np.int64)
    # the first regions: given with their bounds (init_nodes, init_vals: Lemma 6), else sectors of
    # sector0 angles × the whole window
    for x in range(init_nodes.shape[0]):
        for z in range(6):
            nodes[n_nodes, z] = init_nodes[x, z]
        nodes[n_nodes, 6] = 0
        bounds_[n_nodes] = init_vals[x]
        size = _heap_push(hv, hi_, size, init_vals[x], n_nodes)
        n_nodes += 1
    s0 = 0 if init_nodes.shape[0] == 0 else n_ang
    while s0 < n_ang:
        s1 = min(s0 + sector0, n_ang) - 1
        nodes[n_nodes, 0] = s0
        nodes[n_nodes, 1] = s1
        nodes[n_nodes, 2] = 0
        nodes[n_nodes, 3] = side - 1
        nodes[n_nodes, 4] = 0
        nodes[n_nodes, 5] = side - 1
        nodes[n_nodes, 6] = 0
        size = _heap_push(hv, hi_, size, np.inf, n_nodes)
        n_nodes += 1
        s0 = s1 + 1
    free_ids = np.empty(cap, np.int64)
    n_free_ids = 0
    child = np.empty((4, 6), np.int64)
    # per angle, its occupied lattice points for the moving-side bound (Lemma 3b), computed on first use
    p_start = np.full(n_ang, -1, np.int64)  # in p_buf; pre_start ≥ 0: given in pre_buf
    p_cnt = np.zeros(n_ang, np.int64)
    p_buf = np.empty(4096, np.int32)
    p_used = 0
    p_tmp = np.empty(n * n, np.int32)
    r_lo, c_lo = axes_r[3], axes_c[3]
    r_hi, c_hi = r_lo + ref_sat.shape[0] - 2, c_lo + ref_sat.shape[1] - 2
    fr_nodes = np.empty((256 if keep >= 0 else 0, 6), np.int64)
    fr_vals = np.empty(fr_nodes.shape[0], np.float64)
    n_fr = 0
    complete = True
    while size > 0:
        if budget > 0 and n_bounds >= budget:
            complete = False
            break
        _, nid, size = _heap_pop(hv, hi_, size)
        bval = bounds_[nid]
        lo, hi, a0, a1, b0, b1 = nodes[nid, 0], nodes[nid, 1], nodes[nid, 2], nodes[nid, 3], nodes[nid, 4], nodes[nid, 5]
        depth = nodes[nid, 6]
        free_ids[n_free_ids] = nid
        n_free_ids += 1
        # the region's smallest tie keys among its allowed elements
        amin = -1
        for x in range(lo, hi + 1):
            if amask[x]:
                amin = x
                break
        rmin = 1 << 40
        for b in range(b0, b1 + 1):
            for a in range(a0, a1 + 1):
                if tmask[b * side + a] and rank[b * side + a] < rmin:
                    rmin = rank[b * side + a]
        if amin < 0 or rmin == 1 << 40:
            continue
        if mode == 0:
            kp, ks = rmin, amin
        else:
            kp, ks = amin, rmin
        if bval != np.inf and not _before(bval, kp, ks, inc[0], inc[1], inc[2]):
            fr_nodes, fr_vals, n_fr = _dropped(env, lo, hi, a0, a1, b0, b1, bval, inc[0], keep, fr_nodes, fr_vals, n_fr)
            continue
        single = lo == hi and a0 == a1 and b0 == b1
        if single:
            # exact evaluation
            if excl_a[lo] and excl_t[b0 * side + a0]:
                continue
            slot = lo % n_slots
            if code == BIRK_CARPIN:  # free/free: the dense ROI
                if slot_angle[slot] != lo:
                    no, nf = fill_moving(mstates, res_m, mox, moy, mcx, mcy, n, res, rot[lo, 0], rot[lo, 1],
                                         rot[lo, 2], rot[lo, 3], slots_dense[slot], slots_pocc[slot])
                    slot_angle[slot] = lo
                    slot_counts[slot, 0] = no
                    slot_counts[slot, 1] = nf
                agr, dis, ff = exact_counts(slots_dense[slot], slots_pocc[slot], slot_counts[slot, 0], ref, cols,
                                            rows, a0, b0, qr, qc, axes_r[3], axes_c[3], ilo, ihi, jlo, jhi, n,
                                            need_ff)
            else:
                if slot_angle[slot] != lo:
                    if pre_start[lo] >= 0:  # given: a copy
                        no = pre_cnt[lo]
                        slots_pocc[slot, :no] = pre_buf[pre_start[lo]:pre_start[lo] + no]
                    else:
                        gen[0] += 1
                        no = sparse_moving(mstates, res_m, mox, moy, mcx, mcy, n, res, rot[lo, 0], rot[lo, 1],
                                           rot[lo, 2], rot[lo, 3], occ_x, occ_y, mark, gen[0], slots_pocc[slot])
                    slot_angle[slot] = lo
                    slot_counts[slot, 0] = no
                    slot_counts[slot, 1] = 0
                agr, dis = exact_counts_sparse(slots_pocc[slot], slot_counts[slot, 0], ref, cols, rows, a0, b0, qr,
                                               qc, axes_r[3], axes_c[3], ilo, ihi, jlo, jhi, n, mstates, res_m,
                                               mox, moy, mcx, mcy, res, rot[lo, 0], rot[lo, 1], rot[lo, 2],
                                               rot[lo, 3])
                ff = 0
            n_exact += 1
            sx = tsum[b0 * side + a0]
            sy = slot_counts[slot, 0] if code == NCC else slot_counts[slot, 1]
            v = value_of(code, floor, agr, dis, ff, sx, sy, n * n)
            env[lo] = max(env[lo], v)
            if keep >= 0 and v >= inc[0] - keep:
                fr_nodes, fr_vals = _keep(fr_nodes, fr_vals, n_fr, lo, lo, a0, a0, b0, b0, v)
                n_fr += 1
            if _before(v, kp, ks, inc[0], inc[1], inc[2]):
                inc[0], inc[1], inc[2] = v, kp, ks
                inc[3], inc[4], inc[5] = lo, a0 - k, b0 - k
                inc[6], inc[7], inc[8] = agr, dis, ff
            continue
        # split: the angles first (one angle's moving side bounds its box tightly, Lemma 3b), then the box
        nc = 0
        if hi > lo:
            mid = (lo + hi) // 2
            for (x0, x1) in ((lo, mid), (mid + 1, hi)):
                child[nc, 0], child[nc, 1] = x0, x1
                child[nc, 2], child[nc, 3], child[nc, 4], child[nc, 5] = a0, a1, b0, b1
                nc += 1
        else:
            am = (a0 + a1) // 2
            bm = (b0 + b1) // 2
            for (xa0, xa1) in ((a0, am), (am + 1, a1)):
                if xa0 > xa1:
                    continue
                for (xb0, xb1) in ((b0, bm), (bm + 1, b1)):
                    if xb0 > xb1:
                        continue
                    child[nc, 0], child[nc, 1] = lo, hi
                    child[nc, 2], child[nc, 3], child[nc, 4], child[nc, 5] = xa0, xa1, xb0, xb1
                    nc += 1
        for c in range(nc):
            clo, chi = child[c, 0], child[c, 1]
            box[0], box[1], box[2], box[3] = child[c, 2], child[c, 3], child[c, 4], child[c, 5]
            # a region without an allowed angle or translation holds nothing to find: not bounded
            any_a = False
            for x in range(clo, chi + 1):
                if amask[x]:
                    any_a = True
                    break
            any_t = False
            if any_a:
                for b in range(box[2], box[3] + 1):
                    for a in range(box[0], box[1] + 1):
                        if tmask[b * side + a]:
                            any_t = True
                            break
                    if any_t:
                        break
            if not any_t:
                continue
            n_bounds += 1
            sx_lo = 1 << 40
            sx_hi = -1
            if code == NCC or code == BIRK_CARPIN:
                for b in range(box[2], box[3] + 1):
                    for a in range(box[0], box[1] + 1):
                        x = tsum[b * side + a]
                        sx_lo = min(sx_lo, x)
                        sx_hi = max(sx_hi, x)
            sy_lo = 1 << 40
            sy_hi = -1
            if code == NCC or code == BIRK_CARPIN:
                for x in range(clo, chi + 1):
                    sy_lo = min(sy_lo, asum[x])
                    sy_hi = max(sy_hi, asum[x])
            m_agr, m_dis = -1, 0
            if k > 0 and clo == chi:  # one angle: the moving side's bound (Lemma 3b), first
                if pre_start[clo] >= 0:  # its occupied lattice points given
                    m_buf, m_start, m_cnt = pre_buf, pre_start[clo], pre_cnt[clo]
                else:  # computed on first use
                    if p_start[clo] < 0:
                        gen[0] += 1
                        cnt = sparse_moving(mstates, res_m, mox, moy, mcx, mcy, n, res, rot[clo, 0], rot[clo, 1],
                                            rot[clo, 2], rot[clo, 3], occ_x, occ_y, mark, gen[0], p_tmp)
                        p_buf = _append(p_buf, p_used, p_tmp, cnt)
                        p_start[clo] = p_used
                        p_cnt[clo] = cnt
                        p_used += cnt
                    m_buf, m_start, m_cnt = p_buf, p_start[clo], p_cnt[clo]
                m_agr, m_dis = moving_bound(m_buf, m_start, m_cnt, n, rows, cols, ref_sat, r_lo, r_hi, c_lo, c_hi, box)
                ub = upper_of(code, floor, m_agr, m_dis, sx_lo, sx_hi, sy_lo, sy_hi, n * n)
                if ub < inc[0]:
                    # below the incumbent on the moving side alone: dropped now, as its visit would drop it
                    # (the incumbent only grows; the reference side's bound would only lower ub)
                    fr_nodes, fr_vals, n_fr = _dropped(env, clo, chi, box[0], box[1], box[2], box[3], ub, inc[0], keep,
                                                       fr_nodes, fr_vals, n_fr)
                    continue
            th_mid = (angles[clo] + angles[chi]) / 2.0
            half_rad = math.radians((angles[chi] - angles[clo]) / 2.0)
            # the block level: blocks no wider than the region's own blur
            blur = ((box[1] - box[0]) + (box[3] - box[2])) / 4.0 + 2.0 * math.sin(half_rad / 2.0) * rmax / res / 2.0
            level = 0
            while level + 2 < lvl_start.size and (1 << (level + 1)) <= blur:
                level += 1
            agr_hi, dis_lo = region_bound(geo, axes_r, axes_c, blk, blkf, lvl_start, wr0, wc0, ilo, ihi, jlo, jhi, cls_sat,
                                          mh, mw, th_mid, half_rad, box, level)
            if m_agr >= 0:  # both sides (Lemma 3b)
                agr_hi = min(agr_hi, m_agr)
                dis_lo += m_dis
            ub = upper_of(code, floor, agr_hi, dis_lo, sx_lo, sx_hi, sy_lo, sy_hi, n * n)
            if ub < inc[0]:  # dropped now, as its visit would drop it (the incumbent only grows)
                fr_nodes, fr_vals, n_fr = _dropped(env, clo, chi, box[0], box[1], box[2], box[3], ub, inc[0], keep,
                                                   fr_nodes, fr_vals, n_fr)
                continue
            if n_free_ids > 0:
                cid = free_ids[n_free_ids - 1]
                n_free_ids -= 1
            else:
                if n_nodes >= nodes.shape[0]:
                    grown = np.empty((2 * nodes.shape[0], 7), np.int64)
                    grown[:n_nodes] = nodes[:n_nodes]
                    nodes = grown
                    hv2 = np.empty(2 * hv.size, np.float64)
                    hv2[:size] = hv[:size]
                    hv = hv2
                    hi2 = np.empty(2 * hi_.size, np.int64)
                    hi2[:size] = hi_[:size]
                    hi_ = hi2
                    b2 = np.full(2 * bounds_.size, np.inf)
                    b2[:bounds_.size] = bounds_
                    bounds_ = b2
                    fi2 = np.empty(2 * free_ids.size, np.int64)
                    fi2[:n_free_ids] = free_ids[:n_free_ids]
                    free_ids = fi2
                cid = n_nodes
                n_nodes += 1
            for z in range(6):
                nodes[cid, z] = child[c, z]
            nodes[cid, 6] = depth + 1
            if size >= hv.size:
                hv2 = np.empty(2 * hv.size, np.float64)
                hv2[:size] = hv[:size]
                hv = hv2
                hi2 = np.empty(2 * hi_.size, np.int64)
                hi2[:size] = hi_[:size]
                hi_ = hi2
            # visit order (free: only bounds and keys decide): the highest bound, deeper regions first among
            # equal bounds (an incumbent sooner); the region keeps its own bound for the pruning test
            bounds_[cid] = ub
            size = _heap_push(hv, hi_, size, ub + (depth + 1) * 1e-12, cid)
    return n_bounds, n_exact, complete, fr_nodes[:n_fr], fr_vals[:n_fr]
