"""The imprecise-center experiment (issue 9): table and plot from two `circsim sweep` folders.

Run the sweeps, then this script::

    circsim sweep scene1 --grid center_error=0,0.05,0.1,0.2,0.25,0.35,0.5 --grid merger.window_m=0,0.5,1.0 \\
                  --seeds 10 --set duration_s=30 --out runs/window-scene1
    circsim sweep scene2 ... --out runs/window-scene2
    python benchmarks/window_sweep_report.py runs/window-scene1 runs/window-scene2 --png docs/img/window_sweep.png

(the script runs this module's :func:`main`; the module is importable, so tests need no benchmark file).

Per scene, window W and center error: robot-runs whose robot merged correctly (all teammates placed
within 2° and 0.1 m), the median first-merge arc and its ratio to the exact-center median of the same
window, false merges, ~180° order hypotheses that passed verification / were chosen, the median merge
cycle and realtime factor; and whether the issue's targets hold (W = 0.5 m for center errors ≤ 0.25 m,
W = 1.0 m for ≤ 0.5 m: ≥ 95% of robot-runs merged, median arc ≤ 1.2× the exact-center median, 0 false
merges everywhere). No data is "—" in the table and no point in the plot (a cell where nothing merged
has no final error, not one of 0 cm).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from collections import defaultdict
from pathlib import Path


def load(folder: Path) -> list[dict]:
    with open(folder / "runs.jsonl") as f:
        return [json.loads(line) for line in f if line.strip()]


def robots_of(row: dict) -> list[str]:
    return [k.split(".", 1)[1] for k in row if k.startswith("first_merge_arc_deg.") and not k.endswith(".mean")]


def summarize(rows: list[dict]) -> dict:
    cells = defaultdict(list)
    for r in rows:
        cells[(r["scenario"], float(r["merger.window_m"]), float(r["center_error.magnitude_m"]))].append(r)
    out = {}
    for key, rs in sorted(cells.items()):
        arcs = [r.get(f"first_merge_arc_deg.{n}") for r in rs for n in robots_of(rs[0])]
        got = [a for a in arcs if a is not None]
        out[key] = {
            "runs": len(rs), "robot_runs": len(arcs), "merged": len(got),
            "arc_median": statistics.median(got) if got else None,
            "false": sum(r["false_merges"] for r in rs),
            "n180_verified": sum(r.get("near_180_accepted") or 0 for r in rs),
            "n180_chosen": sum(r.get("near_180_chosen") or 0 for r in rs),
            "t_err_max": _most([r.get("final_translation_error_m.max") for r in rs]),  # None: nothing merged
            "cycle_ms": _median([r.get("merge_cycle_ms.median") for r in rs]),
            "rt": statistics.median(r["realtime_factor"] for r in rs),
        }
    return out


def _most(xs):
    known = [x for x in xs if x is not None]
    return max(known) if known else None


def _median(xs):
    known = [x for x in xs if x]
    return statistics.median(known) if known else None


NONE = "—"  # no data (nothing merged, no cycle): never a 0 that reads as a measurement


def table(s: dict) -> list[str]:
    lines = ["| scene | W (m) | center error (m) | robots merged | median first-merge arc | × exact-center median "
             "| false merges | 180° verified / chosen | max final t error | cycle ms | realtime × | target |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for (scene, w, e), c in s.items():
        base = s.get((scene, w, 0.0), {}).get("arc_median")
        ratio = c["arc_median"] / base if c["arc_median"] and base else None
        target = ""
        if (w == 0.5 and e <= 0.25) or (w == 1.0 and e <= 0.5):
            ok = c["merged"] >= 0.95 * c["robot_runs"] and ratio is not None and ratio <= 1.2 and c["false"] == 0
            target = "met" if ok else "**missed**"
        arc = f"{c['arc_median']:.1f}°" if c["arc_median"] is not None else NONE
        t_err = f"{100 * c['t_err_max']:.1f} cm" if c["t_err_max"] is not None else NONE
        cycle = f"{c['cycle_ms']:.0f}" if c["cycle_ms"] is not None else NONE
        lines.append(f"| {scene} | {w:g} | {e:g} | {c['merged']}/{c['robot_runs']} | {arc} | "
                     f"{f'{ratio:.2f}' if ratio else NONE} | {c['false']} | {c['n180_verified']} / "
                     f"{c['n180_chosen']} | {t_err} | {cycle} | {c['rt']:.1f} | {target} |")
    return lines


def plot(s: dict, path: Path):
    """The figure (matplotlib ``Figure``, returned) written to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .plots import dodge, marker

    scenes = sorted({k[0] for k in s})
    fig, axes = plt.subplots(2, len(scenes), figsize=(5.5 * len(scenes), 7), squeeze=False, sharex=True)
    for j, scene in enumerate(scenes):
        windows = sorted({k[1] for k in s if k[0] == scene})
        errors = sorted({k[2] for k in s if k[0] == scene})
        for i, w in enumerate(windows):  # markers and a small offset per window: equal lines both show
            ks = sorted(k for k in s if k[0] == scene and k[1] == w)
            xs = [k[2] + dodge(i, len(windows), errors) for k in ks]
            style = dict(marker=marker(i), ls="-", label=f"W = {w:g} m")
            axes[0][j].plot(xs, [100 * s[k]["merged"] / s[k]["robot_runs"] for k in ks], **style)
            axes[1][j].plot(xs, [s[k]["arc_median"] if s[k]["arc_median"] is not None else float("nan")
                                 for k in ks], **style)
        arcs = [c["arc_median"] for k, c in s.items() if k[0] == scene and c["arc_median"] is not None]
        axes[0][j].set_ylim(-3, 105)  # plain ranges: percentages on [0, 100], arcs from 0
        axes[1][j].set_ylim(0, 1.15 * max(arcs) if arcs else 1.0)
        for ax in (axes[0][j], axes[1][j]):
            ax.set_xticks(errors, [f"{e:g}" for e in errors])  # ticks at the swept errors
        axes[0][j].set_title(scene)
        axes[0][j].set_ylabel("robot-runs merged correctly (%)")
        axes[0][j].axhline(95, color="grey", lw=0.8, ls="--")
        axes[1][j].set_ylabel("median first-merge arc (°)")
        axes[1][j].set_xlabel("center error magnitude (m)")
        for ax in (axes[0][j], axes[1][j]):
            ax.grid(alpha=0.3)
            ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return fig


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=Path, help="sweep output folders (with runs.jsonl)")
    ap.add_argument("--png", type=Path, help="write the plot here")
    args = ap.parse_args(argv)
    missing = [str(f) for f in args.folders if not (f / "runs.jsonl").is_file()]
    if missing:
        ap.error(f"no runs.jsonl in {', '.join(missing)}")
    rows = []
    for folder in args.folders:
        got = load(folder)
        if not got:
            print(f"window_sweep_report: error: {folder}/runs.jsonl holds no finished run", file=sys.stderr)
            return 2
        if not all("merger.window_m" in r for r in got):
            print(f"window_sweep_report: error: {folder}: this sweep did not vary the window (no "
                  f"merger.window_m column); sweep it with --grid merger.window_m=0,0.5,1.0 "
                  f"--grid center_error=...", file=sys.stderr)
            return 2
        rows += got
    s = summarize(rows)
    print("\n".join(table(s)))
    if args.png:
        plot(s, args.png)
        print(f"\nwrote {args.png}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
