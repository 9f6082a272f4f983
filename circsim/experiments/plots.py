"""Plots of a sweep's rows (matplotlib, Agg): metrics vs a swept key (center error when it is swept, else
the first ``--grid`` key), one line per other setting; ticks at the swept values, legend below the panels.

Each panel shows, per x value, the median over seeds and the interquartile band; the "every robot
merged" panel shows the fraction of runs that did. Runs in which no robot merged have no first-merge
figures (the first-merge panels average the robots that merged); a combination without data for a panel
has no point there (never a 0). Lines have their own marker and a small x offset (:func:`dodge`): lines
with equal values stay visible side by side.

Axes are for reading at a glance: plain tick labels (``0.5``, ``2``, ``180``, never ``5.98×10⁻¹``),
y from 0 (every panel is a non-negative quantity; a small margin keeps points at 0 visible), fractions on [0, 1], whole-number ticks for counts,
and a series that is constant (e.g. 0 false merges everywhere) gets a range around its value, not
±4 % of nothing. The angle-error panel is linear up to the 2° correctness tolerance and logarithmic
above it (flips of 180° stay on the page), with fixed ticks at round angles.
"""

from __future__ import annotations

import json
from pathlib import Path

from .tables import counted

PANELS = (
    ("first_merge_s.mean", "first correct merge [s] (mean over robots)"),
    ("first_merge_arc_deg.mean", "arc travelled at first correct merge [°]"),
    ("all_merged", "runs with every robot merged [fraction]"),
    ("false_merges", "false merges per run"),
    ("rejected_correct_rate", "rejected-correct rate (per merge cycle)"),
    ("top_error_deg.median", "angle error of the best hypothesis [°] (median over cycles)"),
)
X_KEY = "center_error.magnitude_m"


FRACTIONS = {"all_merged"}  # 0/1 per run: plotted as the fraction of runs, without a band
UNIT_RANGE = FRACTIONS | {"rejected_correct_rate"}  # never above 1
COUNTS = {"false_merges"}  # whole numbers per run
ANGLE_METRIC = "top_error_deg.median"  # symlog: linear to the 2° tolerance, logarithmic above
ANGLE_TICKS = (0.0, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 45.0, 90.0, 180.0)


def _band(values, fraction: bool = False):
    import numpy as np

    v = np.array([float(x) for x in values if x is not None], dtype=float)
    if v.size == 0:
        return None
    if fraction:
        m = float(v.mean())
        return m, m, m
    return np.percentile(v, 25), np.median(v), np.percentile(v, 75)


MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "*")


def marker(i: int) -> str:
    """The marker of line ``i``: lines that coincide still show (each its own shape)."""
    return MARKERS[i % len(MARKERS)]


def dodge(i: int, n: int, xs) -> float:
    """The x offset of line ``i`` of ``n`` at the values ``xs``: lines side by side within ±1.5 % of the span
    of ``xs`` (of 1 for a single value), so equal values do not hide each other."""
    xs = sorted(set(float(x) for x in xs))
    span = (xs[-1] - xs[0]) if len(xs) > 1 else 1.0
    return 0.0 if n < 2 else (i - (n - 1) / 2) * 0.03 * span / (n - 1)


def _plain(v, _pos=None) -> str:
    """A tick label as a person writes it: 0.5, 2, 180, 0.025."""
    return f"{v:.6g}"


def style_y(ax, metric: str, top: float | None) -> None:
    """Y range, ticks and labels of one panel; ``top`` is the largest value plotted (None: nothing)."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, MaxNLocator, NullLocator

    top = 0.0 if top is None or top != top else max(0.0, top)
    if metric == ANGLE_METRIC:
        ax.set_yscale("symlog", linthresh=2.0, linscale=1.0)  # 2°: the correctness tolerance
        ceiling = next((t for t in ANGLE_TICKS if t >= top * 1.05), 180.0) if top > 0 else 2.0
        ax.set_ylim(-0.04, max(ceiling, 2.0))
        ax.yaxis.set_major_locator(FixedLocator([t for t in ANGLE_TICKS if t <= max(ceiling, 2.0)]))
        ax.yaxis.set_minor_locator(NullLocator())
    elif metric in UNIT_RANGE:
        upper = 1.05 if metric in FRACTIONS or top > 0.5 else max(0.1, top * 1.15)
        ax.set_ylim(-0.03 * upper, upper)  # a point at 0 stays visible above the axis
        ax.yaxis.set_major_locator(MaxNLocator(nbins=6, steps=[1, 2, 2.5, 5, 10]))
    else:
        upper = top * 1.15 if top > 0 else 1.0
        ax.set_ylim(-0.03 * upper, upper)
        ax.yaxis.set_major_locator(MaxNLocator(nbins=6, integer=metric in COUNTS, steps=[1, 2, 2.5, 5, 10]))
    ax.yaxis.set_major_formatter(FuncFormatter(_plain))


def choose_axes(grid_keys: list[str]) -> tuple[str, list[str]]:
    """(x-axis key, line keys) for a sweep over ``grid_keys``: center error if swept, else the first key."""
    if not grid_keys or X_KEY in grid_keys:
        return X_KEY, [k for k in grid_keys if k != X_KEY]
    return grid_keys[0], grid_keys[1:]


def x_position(values: list) -> tuple[dict, list, list]:
    """({value as JSON: x}, ticks, tick labels): numbers at their value; anything else (e.g. method
    names) at 0, 1, 2, ... in label order."""
    if all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
        xs = sorted(set(values))
        return {json.dumps(v): float(v) for v in xs}, [float(v) for v in xs], [f"{v:g}" for v in xs]
    labels = sorted({json.dumps(v) for v in values})
    pos = {lab: float(i) for i, lab in enumerate(labels)}
    return pos, list(pos.values()), [lab.strip('"') for lab in labels]


def plot_sweep(rows: list[dict], line_keys: list[str], path: Path, *, title: str = "", x_key: str = X_KEY) -> Path:
    """A 2×3 figure of :data:`PANELS` vs ``x_key``; lines by the values of ``line_keys``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = sweep_figure(rows, line_keys, title=title, x_key=x_key)
    import io

    from merger.io.mapio import write_files

    buf = io.BytesIO()
    fig.savefig(buf, dpi=90, format="png")
    plt.close(fig)
    write_files({Path(path): buf.getvalue()})  # atomic, like every other output
    return Path(path)


def sweep_figure(rows: list[dict], line_keys: list[str], *, title: str = "", x_key: str = X_KEY):
    """The figure of :func:`plot_sweep` (matplotlib ``Figure``), for tests and notebooks."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xmap, ticks, tick_labels = x_position([r.get(x_key) for r in rows])
    xs = sorted(set(xmap.values()))
    lines: dict[str, list[dict]] = {}
    for r in rows:
        label = ", ".join(f"{k}={json.dumps(r.get(k))}" for k in line_keys) or "all runs"
        lines.setdefault(label, []).append(r)
    span = (xs[-1] - xs[0]) if len(xs) > 1 else 1.0
    fig, axes = plt.subplots(2, 3, figsize=(15, 8.5), constrained_layout=True)
    for ax, (metric, ylabel) in zip(axes.flat, PANELS, strict=True):
        top = None
        for k, (label, rs) in enumerate(sorted(lines.items())):
            shift = dodge(k, len(lines), xs)
            pts = []
            for x in xs:
                b = _band([float(r[metric]) if r.get(metric) is not None else None for r in rs
                           if xmap[json.dumps(r.get(x_key))] == x],
                          fraction=metric in FRACTIONS)
                if b is not None:  # no data (e.g. no correct hypothesis to reject): no point
                    pts.append((x + shift, *b))
            if not pts:
                continue
            x, lo, med, hi = zip(*pts, strict=True)
            top = max(top or 0.0, *map(float, hi), *map(float, med))
            colour = f"C{k % 10}"
            ax.plot(x, med, marker=marker(k), ls="-", color=colour, label=label)
            ax.fill_between(x, lo, hi, color=colour, alpha=0.2, linewidth=0)
        if xs:
            ax.set_xlim(xs[0] - 0.06 * span, xs[-1] + 0.06 * span)
        ax.set_xlabel("center error [m]" if x_key == X_KEY else x_key)
        ax.set_xticks(ticks if len(ticks) <= 12 else ticks[::max(1, len(ticks) // 12)])
        ax.set_xticklabels(tick_labels if len(ticks) <= 12 else tick_labels[::max(1, len(ticks) // 12)],
                           rotation=30 if max(map(len, tick_labels), default=0) > 4 else 0, fontsize=8)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        style_y(ax, metric, top)
        if metric == ANGLE_METRIC:
            ax.axhline(2.0, color="grey", lw=0.8, ls="--")  # the correctness tolerance
    handles, labels = next(((h, lab) for h, lab in (ax.get_legend_handles_labels() for ax in axes.flat) if h),
                           ([], []))
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncols=min(len(labels), 4), fontsize=9)
    seeds = len({r["seed"] for r in rows})
    fig.suptitle(f"{title}  (median and IQR over {counted(seeds, 'seed')})".strip())
    return fig
