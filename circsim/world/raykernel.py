"""The laser's segment kernel for worlds of many walls (a map world's thousands of cell edges).

The contract: :func:`segments_alpha` lowers ``alpha`` (one entry per beam, the fraction of ``range_max``
at which the beam's first hit lies) by every segment's hit, exactly as the numpy path of
:func:`circsim.world.laser.raycast` does: the same beams per segment (its angular window from the laser,
± one beam, both wraps of 2π) and Chipmunk's arithmetic step by step
(``cpSegmentShapeSegmentQuery`` with zero radii), in float64 without fastmath, so both paths give the same
bits (``tests/circsim/world/test_mapgeometry.py`` checks it). The numpy path builds an array entry per
(beam, segment) pair; this loop builds none, which is what thousands of segments need. Compiled through
:func:`merger.jit.njit` (the guarded cache).
"""

from __future__ import annotations

import math

import numpy as np

from merger.jit import njit

_TINY = np.finfo(np.float64).tiny  # Chipmunk's CPFLOAT_MIN in cpvnormalize


@njit(cache=True, nogil=True)
def segments_alpha(ax: float, ay: float, angle_start: float, inc: float, bx: np.ndarray, by: np.ndarray,
                   seg: np.ndarray, alpha: np.ndarray) -> None:
    beams = alpha.shape[0]
    two_pi = 2.0 * np.pi
    for i in range(seg.shape[0]):
        s0x, s0y, s1x, s1y = seg[i, 0], seg[i, 1], seg[i, 2], seg[i, 3]
        pa = math.atan2(s0y - ay, s0x - ax)
        sweep = math.atan2(s1y - ay, s1x - ax) - pa
        sweep = (sweep + np.pi) % two_pi - np.pi
        lo = pa + min(sweep, 0.0)
        span = abs(sweep)
        rel = (lo - angle_start) % two_pi
        vx, vy = s1x - s0x, s1y - s0y
        inv = 1.0 / (math.sqrt(vx * vx + vy * vy) + _TINY)
        nx, ny = vy * inv, -(vx * inv)
        d = (s0x - ax) * nx + (s0y - ay) * ny
        sax, say = s0x + (-ax), s0y + (-ay)
        sbx, sby = s1x + (-ax), s1y + (-ay)
        for shift in (0.0, -two_pi):
            first = max(math.floor((rel + shift) / inc) - 1.0, 0.0)
            last = min(math.ceil((rel + shift + span) / inc) + 1.0, beams - 1.0)
            for k in range(int(first), int(last) + 1):
                dx, dy = bx[k] - ax, by[k] - ay
                if (dx * say - dy * sax) * (dx * sby - dy * sbx) <= 0.0:
                    ad = -d
                    bd = (dx * nx + dy * ny) - d
                    if ad * bd < 0.0:
                        a = ad / (ad - bd)
                        if a < alpha[k]:
                            alpha[k] = a
