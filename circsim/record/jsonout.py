"""Numbers as circsim writes them (run JSON, sweep rows, offline results): floats rounded to 12
significant digits at output, so ``8.6`` prints as ``8.6``, not ``8.600000000000001``.

Twelve significant digits keep everything a user reads from these files (simulated times on a 0.1 s
clock, angles to 0.1° and below, translations to the micrometre, milliseconds of wall time) and drop
only the binary representation error of sums like 86 × 0.1. Computation is never rounded: only what
is written. Non-finite floats, ints, bools, strings and None pass unchanged.
"""

from __future__ import annotations

import json
import math
from typing import Any

SIGNIFICANT_DIGITS = 12


def rounded(value: Any, digits: int = SIGNIFICANT_DIGITS) -> Any:
    """``value`` with every float (in dicts, lists and tuples, recursively) rounded to ``digits``
    significant digits; containers are copied (tuples become lists, as JSON writes them)."""
    if isinstance(value, float):
        return float(f"{value:.{digits}g}") if math.isfinite(value) else value
    if isinstance(value, dict):
        return {k: rounded(v, digits) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [rounded(v, digits) for v in value]
    return value


def dumps(value: Any, **kwargs) -> str:
    """``json.dumps`` of :func:`rounded` ``value`` (same keyword arguments)."""
    return json.dumps(rounded(value), **kwargs)
