"""The branch and bound: best-first over regions (angle range × translation box), exactly the reference's
answer (docs/design/search.md §5, Lemma 5).

Cartographer's fast correlative scan matcher in our terms: a region is a range ``lo..hi`` of the
search's angles × a box ``(a0, a1, b0, b1)`` of translation indices, bounded by
:func:`merger.search.bounds.region_upper`. The highest bound is visited first; a region whose bound
key cannot come before the incumbent in the reference's order is dropped (the envelope of its angles
raised to its bound, and kept in the frontier when asked); a single element is evaluated exactly
(:mod:`merger.search.counts`); any other region is split — its angles first, then its box.

Every array arrives named: :class:`merger.search.prepared.Tables` (the problem), :class:`Work` (the
searcher's scratch: the moving ROIs kept per angle) and :class:`Query` (what this search asks).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..jit import njit
from ..measures import angle_sum, value_of
from .bounds import region_upper
from .counts import exact_counts, exact_counts_sparse, fill_moving, sparse_moving

NO_RANK = 1 << 40  # larger than any tie rank
# the incumbent: its value and tie keys (mode 0: (rank, angle), mode 1: (angle, rank)), its element (angle
# index, translation (a, b) in cells) and counts; angle −1: nothing found yet
INCUMBENT = np.dtype([("value", np.float64), ("key_p", np.int64), ("key_s", np.int64), ("angle", np.int64),
                      ("a", np.int64), ("b", np.int64), ("agr", np.int64), ("dis", np.int64), ("ff", np.int64)])


class Work(NamedTuple):
    """A searcher's scratch, kept between its searches: the moving ROIs of up to ``slot_angle.size``
    angles (dense states, occupied points, their counts) and the marks of :func:`sparse_moving`."""

    slots_dense: np.ndarray  # (slots, n·n) uint8, read only where slot_angle says filled
    slots_pocc: np.ndarray  # (slots, n·n) int32
    slot_angle: np.ndarray  # (slots,) the angle index each slot holds, −1: none
    slot_counts: np.ndarray  # (slots, 2) occupied and free points of each slot's ROI
    mark: np.ndarray  # (n·n,) int32: lattice points seen by sparse_moving, by generation
    gen: np.ndarray  # (1,) the generation
    tmp: np.ndarray  # (n·n,) int32


class Query(NamedTuple):
    """What one branch and bound asks (see :meth:`merger.search.searcher.Searcher.run`)."""

    angles: np.ndarray  # the angles searched (degrees)
    rot: np.ndarray  # their R(−θ) entries (angles, 4)
    amask: np.ndarray  # the angles allowed
    tmask: np.ndarray  # the translations allowed, index b·(2K+1) + a
    rank: np.ndarray  # each translation's tie rank
    asum: np.ndarray  # the measure's count table per angle
    excl_a: np.ndarray  # excl_a × excl_t: elements excluded
    excl_t: np.ndarray
    init_nodes: np.ndarray  # the first regions (m, 6) with their bounds (m) — none: sectors
    init_vals: np.ndarray
    pre_start: np.ndarray  # the moving ROI's occupied points per angle, given (start −1: computed here)
    pre_cnt: np.ndarray
    pre_buf: np.ndarray
    mode: int  # 0: elements ordered by (value, −rank, −angle); 1: by (value, −angle, −rank)
    sector0: int  # the first regions: sectors of this many angles × the whole window
    budget: int  # the most regions bounded (0: no limit)
    keep: float  # ≥ 0: the frontier within this of the incumbent is returned


@njit(cache=True, nogil=True)
def branch_and_bound(t, w, q, inc, env):
    """Best-first branch and bound (Lemma 5). ``inc``: the incumbent, one :data:`INCUMBENT` record updated
    in place; ``env``: per angle the largest bound or exact value seen (an upper
    envelope of its best value over translations). Returns (regions bounded, exact evaluations, whether
    the search completed within the budget — the incumbent is then the answer —, the frontier regions
    (m, 6) and their bounds (m): with ``q.keep`` ≥ 0 the regions dropped and elements evaluated whose
    bound was at least the incumbent − keep at that moment, Lemma 5b)."""
    best = inc[0]
    hk, hb, hn, size = _first_regions(t, q)
    reg = np.empty(6, np.int64)  # the region visited
    child = np.empty((4, 6), np.int64)
    pts = [np.empty(0, np.int32) for _ in range(q.angles.size)]  # per angle, computed on first use
    have = np.zeros(q.angles.size, np.bool_)
    fr_nodes = np.empty((256 if q.keep >= 0 else 0, 6), np.int64)
    fr_vals = np.empty(fr_nodes.shape[0], np.float64)
    n_fr = n_bounds = n_exact = 0
    # the arrays read in the loop as locals: a field of a named tuple read in a loop costs its reference
    # count every time (measured: the coarse windowed search 11% slower)
    amask, tmask, rank, excl_a, excl_t, angles, asum = q.amask, q.tmask, q.rank, q.excl_a, q.excl_t, q.angles, q.asum
    side, k, keep, budget, mode = t.side, t.k, q.keep, q.budget, q.mode
    while size > 0:
        if budget > 0 and n_bounds >= budget:
            return n_bounds, n_exact, False, fr_nodes[:n_fr], fr_vals[:n_fr]
        size, bound, depth = _pop(hk, hb, hn, size, reg)
        kp, ks = _first_keys(amask, tmask, rank, side, mode, reg)
        if kp < 0:
            continue  # nothing allowed in it
        if bound != np.inf and not _before(bound, kp, ks, best.value, best.key_p, best.key_s):
            fr_nodes, fr_vals, n_fr = _dropped(env, reg, bound, best.value, keep, fr_nodes, fr_vals, n_fr)
            continue
        if reg[0] == reg[1] and reg[2] == reg[3] and reg[4] == reg[5]:  # one element: exactly
            if excl_a[reg[0]] and excl_t[reg[4] * side + reg[2]]:
                continue
            agr, dis, ff, v = _evaluate(t, w, q, reg[0], reg[2], reg[4])
            n_exact += 1
            env[reg[0]] = max(env[reg[0]], v)
            if keep >= 0 and v >= best.value - keep:
                fr_nodes, fr_vals, n_fr = _keep(fr_nodes, fr_vals, n_fr, reg, v)
            if _before(v, kp, ks, best.value, best.key_p, best.key_s):
                best.value, best.key_p, best.key_s = v, kp, ks
                best.angle, best.a, best.b = reg[0], reg[2] - k, reg[4] - k
                best.agr, best.dis, best.ff = agr, dis, ff
            continue
        for c in range(_split(reg, child)):
            if not _allowed(amask, tmask, side, child[c]):
                continue  # holds nothing to find: not bounded
            n_bounds += 1
            lo, hi = child[c, 0], child[c, 1]
            pl = _points(t, w, q, pts, have, lo) if k > 0 and lo == hi else pts[lo]
            ub = region_upper(t, angles, asum, lo, hi, child[c, 2:], pl, best.value)
            if ub < best.value:  # dropped now, as its visit would drop it (the incumbent only grows)
                fr_nodes, fr_vals, n_fr = _dropped(env, child[c], ub, best.value, keep, fr_nodes, fr_vals, n_fr)
                continue
            # visit order (free: only bounds and keys decide): the highest bound, deeper regions first among
            # equal bounds (an incumbent sooner); the region keeps its own bound for the pruning test
            hk, hb, hn, size = _push(hk, hb, hn, size, ub + (depth + 1) * 1e-12, ub, child[c], depth + 1)
    return n_bounds, n_exact, True, fr_nodes[:n_fr], fr_vals[:n_fr]


@njit(cache=True, nogil=True)
def _first_regions(t, q):
    """The heap of the first regions: given with their bounds (Lemma 5c: the polar bounds of Lemma 6, a
    frontier of Lemma 5b, an envelope, the guard's unbounded quadrants), else sectors of ``q.sector0``
    angles × the whole window, unbounded."""
    cap = max(4096, 2 * q.init_nodes.shape[0])
    hk = np.empty(cap, np.float64)  # the visit key
    hb = np.empty(cap, np.float64)  # the region's own bound
    hn = np.empty((cap, 7), np.int64)  # angle lo, hi, a0, a1, b0, b1, depth
    size = 0
    reg = np.zeros(6, np.int64)
    for x in range(q.init_nodes.shape[0]):
        hk, hb, hn, size = _push(hk, hb, hn, size, q.init_vals[x], q.init_vals[x], q.init_nodes[x], 0)
    if q.init_nodes.shape[0] == 0:
        reg[3] = reg[5] = t.side - 1
        for s0 in range(0, q.angles.size, q.sector0):
            reg[0], reg[1] = s0, min(s0 + q.sector0, q.angles.size) - 1
            hk, hb, hn, size = _push(hk, hb, hn, size, np.inf, np.inf, reg, 0)
    return hk, hb, hn, size


@njit(cache=True, nogil=True, inline=True)
def _first_keys(amask, tmask, rank, side, mode, reg):
    """The region's smallest tie keys among its allowed elements (mode 0: (rank, angle); mode 1: (angle,
    rank)), (−1, −1) when it allows none."""
    amin = -1
    for x in range(reg[0], reg[1] + 1):
        if amask[x]:
            amin = x
            break
    if amin < 0:  # no angle allowed: the box is not read (a local search's 353 other sectors × the window)
        return -1, -1
    rmin = NO_RANK
    for b in range(reg[4], reg[5] + 1):
        for a in range(reg[2], reg[3] + 1):
            i = b * side + a
            if tmask[i] and rank[i] < rmin:
                rmin = rank[i]
    if amin < 0 or rmin == NO_RANK:
        return -1, -1
    return (rmin, amin) if mode == 0 else (amin, rmin)


@njit(cache=True, nogil=True, inline=True)
def _allowed(amask, tmask, side, reg):
    """Whether the region holds an allowed angle and an allowed translation."""
    for x in range(reg[0], reg[1] + 1):
        if amask[x]:
            for b in range(reg[4], reg[5] + 1):
                for a in range(reg[2], reg[3] + 1):
                    if tmask[b * side + a]:
                        return True
            return False
    return False


@njit(cache=True, nogil=True, inline=True)
def _split(reg, child):
    """The region's children into ``child``: its angles halved, or (one angle) its box in quarters
    (one angle's moving side bounds its box tightly, Lemma 3b). Returns their number."""
    lo, hi, a0, a1, b0, b1 = reg[0], reg[1], reg[2], reg[3], reg[4], reg[5]
    nc = 0
    if hi > lo:
        mid = (lo + hi) // 2
        for (x0, x1) in ((lo, mid), (mid + 1, hi)):
            child[nc, 0], child[nc, 1], child[nc, 2], child[nc, 3], child[nc, 4], child[nc, 5] = x0, x1, a0, a1, b0, b1
            nc += 1
        return nc
    am = (a0 + a1) // 2
    bm = (b0 + b1) // 2
    for (xa0, xa1) in ((a0, am), (am + 1, a1)):
        for (xb0, xb1) in ((b0, bm), (bm + 1, b1)):
            if xa0 <= xa1 and xb0 <= xb1:
                child[nc, 0], child[nc, 1], child[nc, 2], child[nc, 3], child[nc, 4], child[nc, 5] = lo, hi, xa0, xa1, xb0, xb1
                nc += 1
    return nc


@njit(cache=True, nogil=True)
def _evaluate(t, w, q, x, ai, bi):
    """(agr, dis, ff, value) at angle index ``x`` and translation index (ai, bi), the moving ROI under
    that angle kept in slot x mod slots (dense when the measure counts free/free)."""
    slot = x % w.slot_angle.size
    if w.slot_angle[slot] != x:
        if t.need_ff:
            no, nf = fill_moving(t, q.rot[x], w.slots_dense[slot], w.slots_pocc[slot])
        elif q.pre_start[x] >= 0:  # given: a copy
            no, nf = q.pre_cnt[x], 0
            w.slots_pocc[slot, :no] = q.pre_buf[q.pre_start[x]:q.pre_start[x] + no]
        else:
            w.gen[0] += 1
            no, nf = sparse_moving(t, q.rot[x], w.mark, w.gen[0], w.slots_pocc[slot]), 0
        w.slot_angle[slot] = x
        w.slot_counts[slot, 0] = no
        w.slot_counts[slot, 1] = nf
    no, nf = w.slot_counts[slot, 0], w.slot_counts[slot, 1]
    if t.need_ff:
        agr, dis, ff = exact_counts(t, w.slots_dense[slot], w.slots_pocc[slot], no, ai, bi, True)
    else:
        agr, dis = exact_counts_sparse(t, w.slots_pocc[slot], no, ai, bi, q.rot[x])
        ff = 0
    v = value_of(t.code, t.floor, agr, dis, ff, t.tsum[bi * t.side + ai], angle_sum(t.sums, no, nf), t.n * t.n)
    return agr, dis, ff, v


@njit(cache=True, nogil=True, inline=True)
def _points(t, w, q, pts, have, x):
    """The moving ROI's occupied lattice points at angle index ``x``: given in the query, else computed
    on first use."""
    if q.pre_start[x] >= 0:
        return q.pre_buf[q.pre_start[x]:q.pre_start[x] + q.pre_cnt[x]]
    if not have[x]:
        w.gen[0] += 1
        c = sparse_moving(t, q.rot[x], w.mark, w.gen[0], w.tmp)
        pts[x] = w.tmp[:c].copy()
        have[x] = True
    return pts[x]


@njit(cache=True, nogil=True, inline=True)
def _push(hk, hb, hn, size, key, bound, reg, depth):
    """A region onto the max-heap of visit keys (the arrays doubled when full)."""
    if size >= hk.size:
        hk2, hb2, hn2 = np.empty(2 * hk.size), np.empty(2 * hk.size), np.empty((2 * hk.size, 7), np.int64)
        hk2[:size], hb2[:size], hn2[:size] = hk[:size], hb[:size], hn[:size]
        hk, hb, hn = hk2, hb2, hn2
    k = size
    hk[k], hb[k] = key, bound
    for z in range(6):
        hn[k, z] = reg[z]
    hn[k, 6] = depth
    while k > 0:
        p = (k - 1) >> 1
        if hk[p] >= hk[k]:
            break
        _swap(hk, hb, hn, p, k)
        k = p
    return hk, hb, hn, size + 1


@njit(cache=True, nogil=True, inline=True)
def _pop(hk, hb, hn, size, reg):
    """The region of the highest visit key into ``reg`` (6): (new size, its bound, its depth)."""
    bound, depth = hb[0], hn[0, 6]
    for z in range(6):
        reg[z] = hn[0, z]
    size -= 1
    _swap(hk, hb, hn, 0, size)
    k = 0
    while True:
        c = 2 * k + 1
        if c >= size:
            break
        if c + 1 < size and hk[c + 1] > hk[c]:
            c += 1
        if hk[k] >= hk[c]:
            break
        _swap(hk, hb, hn, k, c)
        k = c
    return size, bound, depth


@njit(cache=True, nogil=True, inline=True)
def _swap(hk, hb, hn, i, j):
    hk[i], hk[j] = hk[j], hk[i]
    hb[i], hb[j] = hb[j], hb[i]
    for z in range(7):
        hn[i, z], hn[j, z] = hn[j, z], hn[i, z]


@njit(cache=True, nogil=True)
def _keep(fr_nodes, fr_vals, n_fr, reg, v):
    """A region and its bound appended to the frontier (the arrays grown when full)."""
    if n_fr >= fr_nodes.shape[0]:
        grown = np.empty((2 * fr_nodes.shape[0] + 256, 6), np.int64)
        grown[:n_fr] = fr_nodes[:n_fr]
        grown_v = np.empty(grown.shape[0], np.float64)
        grown_v[:n_fr] = fr_vals[:n_fr]
        fr_nodes, fr_vals = grown, grown_v
    fr_nodes[n_fr, :] = reg[:6]
    fr_vals[n_fr] = v
    return fr_nodes, fr_vals, n_fr + 1


@njit(cache=True, nogil=True, inline=True)
def _dropped(env, reg, v, inc0, keep, fr_nodes, fr_vals, n_fr):
    """A region dropped with bound ``v`` (below the incumbent ``inc0``): the envelope of its angles raised
    to ``v``, and the region kept in the frontier when ``v`` ≥ inc0 − ``keep`` (Lemma 5b)."""
    for x in range(reg[0], reg[1] + 1):
        env[x] = max(env[x], v)
    if keep >= 0 and v >= inc0 - keep:
        return _keep(fr_nodes, fr_vals, n_fr, reg, v)
    return fr_nodes, fr_vals, n_fr


@njit(cache=True, nogil=True, inline=True)
def _before(v, p, s, iv, ip, is_):
    """Whether the key (v, −p, −s) comes before (is greater than) (iv, −ip, −is)."""
    if v != iv:
        return v > iv
    if p != ip:
        return p < ip
    return s < is_
