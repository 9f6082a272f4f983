"""Approximate similarity profile over all angles at once, in polar coordinates (FFT).

Rotating the moving map about the shared center is a circular shift of its polar image. Sampling both
ROIs on the same rings, the agreement and disagreement counts of the thesis's measures (3.3.1) for every
angle are circular cross-correlations along the angle axis, summed over the rings with the area each
sample stands for (ring radius × ring width × angular step), i.e. one FFT product per ring:

    agr̃(θ) ≈ Σ_r w_r Σ_φ O_ref(r, φ) O_mov(r, φ − θ),
    dis(θ)  ≈ Σ_r w_r Σ_φ [O_ref F_mov + F_ref O_mov](r, φ − θ),

with O, F the occupied and free indicators. The grids are first max-pooled (state order
unknown < free < occupied, so a block maximum keeps walls), rings get a band-limited number of samples
(about one per pooled cell of circumference), and only the spectrum up to 180 cycles is kept, which is
what a 1° profile needs. The result ranks the angles well but is not the exact Cartesian measure;
:mod:`merger.fast` only uses it to choose the few angles it then evaluates exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.fft as sfft

from .cache import BoundedCache, array_digest
from .grid import FREE_S, OCCUPIED_S, OccupancyGrid

PROFILE_LEN = 360  # 1° steps
_BINS = PROFILE_LEN // 2 + 1
_RING_LENGTHS = (96, 192, 384, 576)  # FFT-friendly; ~1 sample per pooled cell of arc


def pool_factor(n: int) -> int:
    """Max-pooling factor for an (n, n) ROI: the pooled ROI keeps about 128 cells across."""
    return max(1, int(round(n / 128)))


@dataclass(frozen=True, eq=False)
class PolarLayout:
    """Rings and sample positions for an (n, n) ROI of cell size ``res``, pooled ``pool`` times.

    ``x, y`` are the sample offsets from the center (metres, float32), ``mask``
    keeps samples inside the ROI's square, ``rings`` lists (first sample, ring count, ring length)
    per band and ``weight`` is the square root of every ring's sample area, in pooled cells.
    """

    n: int
    res: float
    pool: int
    x: np.ndarray
    y: np.ndarray
    mask: np.ndarray
    rings: tuple
    weight: np.ndarray
    mask_spec: np.ndarray


@lru_cache(maxsize=16)
def polar_layout(n: int, res: float, pool: int, inscribed: bool = False) -> PolarLayout:
    """The layout; ``inscribed`` keeps only the rings inside the ROI's inscribed circle (fewer samples,
    for a cheaper and rougher profile)."""
    half = n * res / 2.0
    pres = res * pool
    count = int(math.ceil(half * (1.0 if inscribed else math.sqrt(2)) / pres))  # rings out to the corners
    rho = (np.arange(count) + 0.5) * pres
    need = 2 * math.pi * rho / pres
    lengths = np.array([next((b for b in _RING_LENGTHS if b >= x), _RING_LENGTHS[-1]) for x in need])
    xs, ys, rings, weight = [], [], [], []
    start = 0
    for length in np.unique(lengths):
        rr = rho[lengths == length]
        phi = np.arange(length) * (2 * math.pi / length)
        xs.append((rr[:, None] * np.cos(phi)).ravel())
        ys.append((rr[:, None] * np.sin(phi)).ravel())
        rings.append((start, rr.size, int(length)))
        # sample area (pooled cells) × the FFT normalization of a ring of this length at 1° steps
        weight.append(np.sqrt(rr / pres * 2 * math.pi / length * PROFILE_LEN / length))
        start += rr.size * int(length)
    x, y = np.concatenate(xs), np.concatenate(ys)
    mask = (np.abs(x) < half) & (np.abs(y) < half)
    w = np.concatenate(weight).astype(np.float32)
    lay = PolarLayout(n, res, pool, x.astype(np.float32), y.astype(np.float32), mask, tuple(rings), w,
                      np.empty(0))
    object.__setattr__(lay, "mask_spec", _spectra(lay, mask.astype(np.float32)[None]))
    return lay


def _spectra(lay: PolarLayout, values: np.ndarray) -> np.ndarray:
    """(C, rings, 181) complex64 spectra of C per-sample value vectors, each ring weighted by √area."""
    out = np.zeros((values.shape[0], lay.weight.size, _BINS), np.complex64)
    r = 0
    for start, count, length in lay.rings:
        block = values[:, start:start + count * length].reshape(values.shape[0], count, length)
        spec = sfft.rfft(block, axis=-1)
        k = min(spec.shape[-1], _BINS)
        out[:, r:r + count, :k] = spec[..., :k]
        if length < PROFILE_LEN:  # the ring's Nyquist bin counts once, not as a ± pair
            out[:, r:r + count, k - 1] *= np.float32(math.sqrt(0.5))
        r += count
    out *= lay.weight[:, None]
    return out


def _crop(grid: OccupancyGrid, center, lay: PolarLayout):
    """The grid's cells around ``center`` out to the ROI's corners (unknown outside), and the crop's
    origin; the side is a multiple of the pooling factor."""
    res, p = grid.resolution, lay.pool
    return square_crop(grid, center, lay.n * lay.res / 2.0 * math.sqrt(2) + 2 * res * p, p)


def crop_cells(grid: OccupancyGrid, center, reach: float, multiple: int = 1):
    """The grid's cells within ``reach`` metres of ``center`` on each axis (unknown outside the grid), as a
    square whose side is a multiple of ``multiple``; and the grid column and row of its first cell."""
    res = grid.resolution
    c0 = int(math.floor((center[0] - reach - grid.origin[0]) / res))
    r0 = int(math.floor((center[1] - reach - grid.origin[1]) / res))
    size = (int(math.ceil(2 * reach / res)) + 2 + multiple - 1) // multiple * multiple
    crop = np.zeros((size, size), np.uint8)
    gc0, gc1 = max(c0, 0), min(c0 + size, grid.width)
    gr0, gr1 = max(r0, 0), min(r0 + size, grid.height)
    if gc0 < gc1 and gr0 < gr1:
        crop[gr0 - r0:gr1 - r0, gc0 - c0:gc1 - c0] = grid.states[gr0:gr1, gc0:gc1]
    return crop, c0, r0


def square_crop(grid: OccupancyGrid, center, reach: float, multiple: int = 1):
    """:func:`crop_cells`, with the crop's origin (metres) instead of its first cell."""
    crop, c0, r0 = crop_cells(grid, center, reach, multiple)
    return crop, (grid.origin[0] + c0 * grid.resolution, grid.origin[1] + r0 * grid.resolution)


def _max_pool(crop: np.ndarray, p: int) -> np.ndarray:
    """Block maximum over p × p cells (unknown < free < occupied: occupied wins, then free)."""
    if p == 1:
        return crop
    rows = crop[0::p].copy()
    for i in range(1, p):
        np.maximum(rows, crop[i::p], out=rows)
    out = rows[:, 0::p].copy()
    for j in range(1, p):
        np.maximum(out, rows[:, j::p], out=out)
    return out


# Spectra of the maps of recent merge cycles, keyed by layout, crop geometry and the crop's content
# digest: a map unchanged since the previous cycle (or shared by teammates) is not transformed again,
# and a changed one never meets stale spectra. Bounded (an entry is ~0.3 MB for an 8 m ROI at 5 cm):
# a long run publishes a new map every period and must not keep them all.
SPECTRA_ENTRIES = 64
SPECTRA_BYTES = 32 * 2**20
INDEX_ENTRIES = 32  # sample indices by layout and crop geometry (:func:`_sample_index`)
INDEX_BYTES = 32 * 2**20
_CACHE = BoundedCache(SPECTRA_ENTRIES, SPECTRA_BYTES)
_INDEX = BoundedCache(INDEX_ENTRIES, INDEX_BYTES)


def clear_cache() -> None:
    """Forget the cached polar spectra and sample indices, and the windowed search's rotated ROIs
    (benchmarks use this to time cold merge cycles)."""
    from .window import clear_rotation_cache

    _CACHE.clear()
    _INDEX.clear()
    clear_rotation_cache()


def _sample_index(lay: PolarLayout, offset, shape, res: float) -> np.ndarray:
    """Flat index of the pooled cell holding every sample (the extra cell ``size`` when the sample lies
    outside the ROI's square), for a crop whose corner is ``offset`` (metres) from the center. The maps
    of a merge cycle share few lattices (a superposition has its first map's), so it is cached."""
    key = (lay.n, lay.res, lay.pool, lay.weight.size, offset[0], offset[1], shape, res)
    hit = _INDEX.get(key)
    if hit is not None:
        return hit
    inv = np.float32(1.0 / (res * lay.pool))
    ix = (lay.x * inv + np.float32(offset[0] * inv)).astype(np.intp)  # nearest: the pooled
    iy = (lay.y * inv + np.float32(offset[1] * inv)).astype(np.intp)  # cell holding the sample
    np.clip(ix, 0, shape[1] - 1, out=ix)
    np.clip(iy, 0, shape[0] - 1, out=iy)
    iy *= shape[1]
    iy += ix
    iy[~lay.mask] = shape[0] * shape[1]
    iy.setflags(write=False)
    _INDEX.put(key, iy)
    return iy


def polar_spectra(grid: OccupancyGrid, center, lay: PolarLayout) -> np.ndarray:
    """(2, rings, 181) spectra of the occupied and free indicators of ``grid`` around ``center``.

    A map is used several times in a merge cycle (as reference and as moving map) and in the next
    cycles while it is unchanged; spectra are kept in a bounded cache keyed by the cropped cells'
    digest (:func:`merger.cache.array_digest`), so a changed grid is never served stale spectra.
    """
    crop, org = _crop(grid, center, lay)
    geo = (lay.n, lay.res, lay.pool, lay.weight.size, float(center[0] - org[0]), float(center[1] - org[1]),
           grid.resolution)
    key = geo + (array_digest(crop),)
    spec = _CACHE.get(key)
    if spec is not None:
        return spec
    pooled = _max_pool(crop, lay.pool)
    flat = np.zeros(pooled.size + 1, np.uint8)  # and one unknown cell for the samples outside the ROI
    flat[:-1] = pooled.reshape(-1)
    s = flat.take(_sample_index(lay, geo[4:6], pooled.shape, grid.resolution))
    values = np.empty((2, s.size), np.float32)
    np.equal(s, OCCUPIED_S, out=values[0])
    np.equal(s, FREE_S, out=values[1])
    spec = _spectra(lay, values)
    spec.setflags(write=False)
    _CACHE.put(key, spec)
    return spec


def approximate_profile(problem) -> np.ndarray:
    """The problem's measure at 0°, 1°, …, 359°, approximated in polar coordinates (see module doc)."""
    lay = polar_layout(problem.n, problem.ref.resolution, pool_factor(problem.n))
    a = polar_spectra(problem.ref, problem.center_ref, lay)
    b = polar_spectra(problem.moving, problem.center_moving, lay)
    bc = np.conj(b)
    pairs = [a[0] * bc[0], a[0] * bc[1] + a[1] * bc[0]]  # agr, dis
    if problem.measure == "birk_carpin":
        pairs.append(a[1] * bc[1])
    elif problem.measure == "ncc":
        pairs += [lay.mask_spec[0] * bc[0], a[0] * np.conj(lay.mask_spec[0])]  # Σy(θ), Σx
    spec = np.stack([p.sum(axis=0) for p in pairs])
    corr = sfft.irfft(spec, n=PROFILE_LEN, axis=1)  # weighted circular correlations, per degree
    agr, dis = corr[0], corr[1]
    with np.errstate(divide="ignore", invalid="ignore"):
        if problem.measure == "similarity":
            val = agr / (agr + dis)
        elif problem.measure == "birk_carpin":
            val = (agr + corr[2]) / (agr + corr[2] + dis)
        else:
            size = float(problem.n / lay.pool) ** 2  # the ROI's area, pooled cells
            sx, sy = float(corr[3][0]), corr[2]
            vx, vy = sx - sx * sx / size, sy - sy * sy / size
            val = (agr - sx * sy / size) / np.sqrt(np.maximum(vx * vy, 1e-12))
    return np.nan_to_num(val, nan=0.0, posinf=0.0, neginf=0.0)
