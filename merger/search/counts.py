"""Exact counts at one element (θ, t): the moving ROI under an angle, and agr̃, dis (and free/free).

Compiled with ``@njit(cache=True, nogil=True)`` (no fastmath) on the arrays of
:class:`merger.search.prepared.Tables`; the lookups are those of :mod:`merger.lattice`.

* :func:`fill_moving` — the moving ROI under one angle: dense states and its occupied points.
* :func:`sparse_moving` — only its occupied points, from the moving map's occupied cells (no dense ROI);
  :func:`moving_points_all` at every angle of an array at once (kept per moving map by the searcher).
* :func:`exact_counts` / :func:`exact_counts_sparse` — (agr̃, dis[, ff]) at one translation: the moving
  ROI's occupied points read the reference through the tables; the reference's occupied cells read the
  moving ROI through the tables' preimages (Lemma 2); :func:`values_at` — the measure's values at many
  translations of one angle.
"""

from __future__ import annotations

import math

import numpy as np

from ..grid import FREE_S, OCCUPIED_S
from ..jit import njit
from ..lattice import half_side, moving_states, state_at
from ..measures import angle_sum, value_of

HALF_DIAGONAL = 0.7072  # a cell's half-diagonal √½ (cells), rounded up: how far a rotated cell reaches


@njit(cache=True, nogil=True)
def fill_moving(t, r, dense, pocc):
    """The moving ROI of ``t`` under the rotation ``r`` = R(−θ) entries into ``dense`` (n·n) and its
    occupied points into ``pocc``; returns (number of occupied points, number of free points)."""
    n = t.n
    n_occ, n_free = moving_states(t.mstates, t.res_m, t.mox, t.moy, t.mcx, t.mcy, n, t.res, r[0], r[1], r[2],
                                  r[3], dense)
    k = 0
    for p in range(n * n):
        if dense[p] == OCCUPIED_S:
            pocc[k] = p
            k += 1
    return n_occ, n_free


@njit(cache=True, nogil=True)
def sparse_moving(t, r, mark, gen, pocc):
    """The occupied lattice points of the moving ROI under ``r`` into ``pocc``, without the dense ROI:
    each occupied moving cell (centre (occ_x, occ_y) about c_m) is read only by lattice points within a
    half-diagonal of R(θ)(its centre); those candidates are read with
    :func:`merger.lattice.state_at`. ``mark``/``gen``: candidates seen. Returns their number."""
    n = t.n
    m = (n - 1) / 2.0
    half = half_side(n, t.res)
    reach = HALF_DIAGONAL * t.res_m / t.res + 1e-6
    r00, r01, r10, r11 = r[0], r[1], r[2], r[3]
    ms, res_m, mox, moy, mcx, mcy, res = t.mstates, t.res_m, t.mox, t.moy, t.mcx, t.mcy, t.res
    occ_x, occ_y = t.occ_x, t.occ_y
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
                if state_at(ms, res_m, mox, moy, mcx, mcy, m, half, res, r00, r01, r10, r11, i, j) == OCCUPIED_S:
                    pocc[count] = p
                    count += 1
    return count


@njit(cache=True, nogil=True)
def moving_points_all(t, rot):
    """:func:`sparse_moving` at every angle of ``rot`` (rows of R(−θ) entries): the occupied lattice
    points of angle x are ``buf[start[x]:start[x] + cnt[x]]``."""
    n_ang = rot.shape[0]
    start = np.empty(n_ang, np.int64)
    cnt = np.empty(n_ang, np.int64)
    mark = np.zeros(t.n * t.n, np.int32)
    tmp = np.empty(t.n * t.n, np.int32)
    buf = np.empty(max(1024, 2 * t.occ_x.size * n_ang), np.int32)
    used = 0
    for x in range(n_ang):
        c = sparse_moving(t, rot[x], mark, x + 1, tmp)
        buf = append(buf, used, tmp, c)
        start[x] = used
        cnt[x] = c
        used += c
    return start, cnt, buf[:used].copy()


@njit(cache=True, nogil=True)
def append(buf, used, src, c):
    """``src[:c]`` written at ``buf[used:]``, the buffer grown (doubled) when it is too small."""
    if used + c > buf.size:
        grown = np.empty(max(2 * buf.size, used + c), np.int32)
        grown[:used] = buf[:used]
        buf = grown
    buf[used:used + c] = src[:c]
    return buf


@njit(cache=True, nogil=True)
def _moving_occupied_term(t, pocc, n_occ, ai, bi):
    """(agr, dis from the moving side): each occupied lattice point against the reference cell it reads."""
    n, rows, cols, ref = t.n, t.rows, t.cols, t.ref  # locals: fields of t are read again in every iteration
    agr = 0
    dis = 0
    for x in range(n_occ):
        p = pocc[x]
        i = p // n
        j = p - i * n
        r = rows[bi, i]
        c = cols[ai, j]
        if r >= 0 and c >= 0:
            s = ref[r, c]
            if s == OCCUPIED_S:
                agr += 1
            elif s == FREE_S:
                dis += 1
    return agr, dis


@njit(cache=True, nogil=True)
def exact_counts_sparse(t, pocc, n_occ, ai, bi, r):
    """(agr, dis) as :func:`exact_counts`, the moving ROI (rotation ``r``) read point by point."""
    agr, dis = _moving_occupied_term(t, pocc, n_occ, ai, bi)
    m = (t.n - 1) / 2.0
    half = half_side(t.n, t.res)
    r00, r01, r10, r11 = r[0], r[1], r[2], r[3]
    ms, res_m, mox, moy, mcx, mcy, res = t.mstates, t.res_m, t.mox, t.moy, t.mcx, t.mcy, t.res
    qr, qc, ilo, ihi, jlo, jhi, rlo, clo = t.qr, t.qc, t.ilo, t.ihi, t.jlo, t.jhi, t.rlo, t.clo
    for q in range(qr.size):
        rr = qr[q] - rlo
        cc = qc[q] - clo
        for i in range(ilo[bi, rr], ihi[bi, rr]):
            for j in range(jlo[ai, cc], jhi[ai, cc]):
                if state_at(ms, res_m, mox, moy, mcx, mcy, m, half, res, r00, r01, r10, r11, i, j) == FREE_S:
                    dis += 1
    return agr, dis


@njit(cache=True, nogil=True)
def exact_counts(t, dense, pocc, n_occ, ai, bi, need_ff):
    """(agr, dis, ff) of the moving ROI ``dense`` against the reference ROI at translation (ai, bi)."""
    n = t.n
    agr, dis = _moving_occupied_term(t, pocc, n_occ, ai, bi)
    qr, qc, ilo, ihi, jlo, jhi, rlo, clo = t.qr, t.qc, t.ilo, t.ihi, t.jlo, t.jhi, t.rlo, t.clo
    for q in range(qr.size):  # reference occupied: the lattice points that read it, against moving free
        rr = qr[q] - rlo
        cc = qc[q] - clo
        for i in range(ilo[bi, rr], ihi[bi, rr]):
            for j in range(jlo[ai, cc], jhi[ai, cc]):
                if dense[i * n + j] == FREE_S:
                    dis += 1
    ff = 0
    if need_ff:
        rows, cols, ref = t.rows, t.cols, t.ref
        for i in range(n):
            r = rows[bi, i]
            if r < 0:
                continue
            for j in range(n):
                c = cols[ai, j]
                if c >= 0 and ref[r, c] == FREE_S and dense[i * n + j] == FREE_S:
                    ff += 1
    return agr, dis, ff


@njit(cache=True, nogil=True)
def values_at(t, dense, pocc, n_occ, n_free, ai, bi, r, out):
    """The exact values of the moving ROI under ``r`` (its occupied points ``pocc``; ``dense`` when the
    measure counts free/free) at the translation indices (ai[x], bi[x]) into ``out``."""
    tsum, side, code, floor, nn = t.tsum, t.side, t.code, t.floor, t.n * t.n
    sy = angle_sum(t.sums, n_occ, n_free)
    for x in range(ai.size):
        if t.need_ff:
            agr, dis, ff = exact_counts(t, dense, pocc, n_occ, ai[x], bi[x], True)
        else:
            agr, dis = exact_counts_sparse(t, pocc, n_occ, ai[x], bi[x], r)
            ff = 0
        out[x] = value_of(code, floor, agr, dis, ff, tsum[bi[x] * side + ai[x]], sy, nn)


@njit(cache=True, nogil=True)
def values_at_rotations(t, rots, mark, gen, dense, pocc, ai, bi, out):
    """:func:`values_at` at one translation index (``ai``, ``bi``: arrays of one) for each rotation of
    ``rots`` (R(−θ) entries per row), into ``out``: the moving ROI of each angle as :meth:`Searcher.values`
    builds it (dense with free/free, else its occupied points; ``mark``/``gen`` as for
    :func:`sparse_moving`, ``gen`` an array of one advanced here)."""
    for x in range(rots.shape[0]):
        if t.need_ff:
            no, nf = fill_moving(t, rots[x], dense, pocc)
        else:
            gen[0] += 1
            no, nf = sparse_moving(t, rots[x], mark, gen[0], pocc), 0
        values_at(t, dense, pocc, no, nf, ai, bi, rots[x], out[x:x + 1])
