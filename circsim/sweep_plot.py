"""Plots of a sweep's rows (matplotlib, Agg): metrics vs a swept key (center error when it is swept, else
the first ``--grid`` key), one line per other setting; ticks at the swept values, legend below the panels.

Each panel shows, per x value, the median over seeds and the interquartile band; the "every robot
merged" panel shows the fraction of runs that did. Runs in which no robot merged have no first-merge
figures (the first-merge panels average the robots that merged).
"""

from __future__ import annotations

import json
from pathlib import Path

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


def _band(values, fraction: bool = False):
    import numpy as np

    v = np.array([float(x) for x in values if x is not None], dtype=float)
    if v.size == 0:
        return None
    if fraction:
        m = float(v.mean())
        return m, m, m
    return np.percentile(v, 25), np.median(v), np.percentile(v, 75)


def choose_axes(grid_keys: list[str]) -> tuple[str, list[str]]:
    """(x-axis key, line keys) for a sweep over ``grid_keys``: center error if swept, else the first key."""
    if not grid_keys or X_KEY in grid_keys:
        return X_KEY, [k for k in grid_keys if k != X_KEY]
    return grid_keys[0], grid_keys[1:]


def _x_position(values: list) -> tuple[dict, list, list]:
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

    xmap, ticks, tick_labels = _x_position([r.get(x_key) for r in rows])
    xs = sorted(set(xmap.values()))
    lines: dict[str, list[dict]] = {}
    for r in rows:
        label = ", ".join(f"{k}={json.dumps(r.get(k))}" for k in line_keys) or "all runs"
        lines.setdefault(label, []).append(r)
    fig, axes = plt.subplots(2, 3, figsize=(15, 8.5), constrained_layout=True)
    for ax, (metric, ylabel) in zip(axes.flat, PANELS, strict=True):
        for k, (label, rs) in enumerate(sorted(lines.items())):
            pts = []
            for x in xs:
                b = _band([float(r[metric]) if r.get(metric) is not None else None for r in rs
                           if xmap[json.dumps(r.get(x_key))] == x],
                          fraction=metric in FRACTIONS)
                if b is not None:
                    pts.append((x, *b))
            if not pts:
                continue
            x, lo, med, hi = zip(*pts, strict=True)
            colour = f"C{k % 10}"
            ax.plot(x, med, "o-", color=colour, label=label)
            ax.fill_between(x, lo, hi, color=colour, alpha=0.2, linewidth=0)
        ax.set_xlabel("center error [m]" if x_key == X_KEY else x_key)
        ax.set_xticks(ticks if len(ticks) <= 12 else ticks[::max(1, len(ticks) // 12)])
        ax.set_xticklabels(tick_labels if len(ticks) <= 12 else tick_labels[::max(1, len(ticks) // 12)],
                           rotation=30 if max(map(len, tick_labels), default=0) > 4 else 0, fontsize=8)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        if metric == "top_error_deg.median":
            ax.set_yscale("symlog", linthresh=2.0)  # 2° is the correctness tolerance; 180° flips go far up
    handles, labels = next(((h, lab) for h, lab in (ax.get_legend_handles_labels() for ax in axes.flat) if h),
                           ([], []))
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncols=min(len(labels), 4), fontsize=9)
    seeds = len({r["seed"] for r in rows})
    fig.suptitle(f"{title}  (median and IQR over {seeds} seeds)".strip())
    import io

    from merger.mapio import write_files

    buf = io.BytesIO()
    fig.savefig(buf, dpi=90, format="png")
    plt.close(fig)
    write_files({Path(path): buf.getvalue()})  # atomic, like every other output
    return Path(path)
