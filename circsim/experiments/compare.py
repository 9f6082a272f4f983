"""The merging methods compared on the same truth (issue 35): tables and a plot from sweep rows and real-map
verdicts. ``benchmarks/compare_algorithms.py`` runs the cases (a ``circsim sweep`` per scene over
``merger.algorithm`` × center error, and every real-map pair merged by each method) and calls these.

Simulated scenes, per (scene, algorithm, center error), over the sweep's runs: the fraction of robots that
merged every teammate's map correctly (``robots_merged`` / team), the mean first correct merge over the
robots that did, false merges per run, merge cycle cost (median of the runs' medians). Real maps, per (set,
algorithm): pairs correct-accepted / false (accepted, not correct) / refused, and the median time per pair.
"""

from __future__ import annotations

import json
import statistics
from pathlib import Path

ALGORITHM_KEY = "merger.algorithm"
ERROR_KEY = "center_error.magnitude_m"


def _algorithm(row: dict) -> str:
    return json.loads(row[ALGORITHM_KEY]) if str(row[ALGORITHM_KEY]).startswith('"') else str(row[ALGORITHM_KEY])


def sim_summary(rows: list[dict], team: dict[str, int]) -> list[dict]:
    """One dict per (scene, algorithm, center error) of sweep rows (``runs.jsonl``); ``team``: robots per scene."""
    groups: dict = {}
    for r in rows:
        if r.get("interrupted"):
            continue
        groups.setdefault((r["scenario"], _algorithm(r), float(r[ERROR_KEY])), []).append(r)
    out = []
    for (scene, alg, err), rs in sorted(groups.items()):
        firsts = [r["first_merge_s.mean"] for r in rs if r.get("first_merge_s.mean") is not None]
        costs = [r["merge_cycle_ms.median"] for r in rs if r.get("merge_cycle_ms.median") is not None]
        out.append({"scene": scene, "algorithm": alg, "center_error_m": err, "runs": len(rs),
                    "merged_fraction": statistics.mean(r["robots_merged"] / team[scene] for r in rs),
                    "first_merge_s": statistics.mean(firsts) if firsts else None,
                    "false_merges": statistics.mean(r["false_merges"] for r in rs),
                    "cycle_ms": statistics.median(costs) if costs else None})
    return out


def real_summary(verdicts: list[dict]) -> list[dict]:
    """One dict per (set, algorithm) of pair verdicts ``{"set", "algorithm", "accepted", "correct", "ms"}``."""
    groups: dict = {}
    for v in verdicts:
        groups.setdefault((v["set"], v["algorithm"]), []).append(v)
    out = []
    for (s, alg), vs in groups.items():
        out.append({"set": s, "algorithm": alg, "pairs": len(vs),
                    "correct": sum(1 for v in vs if v["accepted"] and v["correct"]),
                    "false": sum(1 for v in vs if v["accepted"] and not v["correct"]),
                    "refused": sum(1 for v in vs if not v["accepted"]),
                    "ms": statistics.median(v["ms"] for v in vs)})
    return out


def _f(v, fmt: str) -> str:
    return "—" if v is None else format(v, fmt)


def sim_table(summary: list[dict], algorithms: list[str]) -> str:
    """Markdown: a row per (scene, center error), per algorithm "merged % / first merge s / false per run"."""
    head = "| scene | center error | " + " | ".join(algorithms) + " |"
    lines = [head, "|" + "---|" * (2 + len(algorithms))]
    keys = sorted({(s["scene"], s["center_error_m"]) for s in summary}, key=lambda k: (k[0], k[1]))
    by = {(s["scene"], s["center_error_m"], s["algorithm"]): s for s in summary}
    for scene, err in keys:
        cells = []
        for a in algorithms:
            s = by.get((scene, err, a))
            cells.append("—" if s is None else f"{100 * s['merged_fraction']:.0f}% / {_f(s['first_merge_s'], '.1f')} s"
                         f" / {s['false_merges']:.1f} ({_f(s['cycle_ms'], '.0f')} ms)")
        lines.append(f"| {scene} | {err:g} m | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def real_table(summary: list[dict], algorithms: list[str]) -> str:
    """Markdown: a row per real-map set, per algorithm "correct / false / refused (median time)"."""
    lines = ["| set | pairs | " + " | ".join(algorithms) + " |", "|" + "---|" * (2 + len(algorithms))]
    by = {(s["set"], s["algorithm"]): s for s in summary}
    for name in dict.fromkeys(s["set"] for s in summary):
        n = next(s["pairs"] for s in summary if s["set"] == name)
        cells = ["—" if (name, a) not in by else
                 f"{by[(name, a)]['correct']} / {by[(name, a)]['false']} / {by[(name, a)]['refused']} "
                 f"({by[(name, a)]['ms']:.0f} ms)" for a in algorithms]
        lines.append(f"| {name} | {n} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot(sim: list[dict], real: list[dict], algorithms: list[str], path: Path) -> Path:
    """Small multiples: per scene, robots merged, first merge and false merges against the center error (a
    line per algorithm); below, the real-map sets' correct / false / refused pairs per algorithm."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(s["scene"] for s in sim))
    sets = list(dict.fromkeys(s["set"] for s in real))
    ncol = max(len(scenes), 1)
    fig, axes = plt.subplots(4, ncol, figsize=(4.2 * ncol, 12), squeeze=False)
    panels = (("merged_fraction", "robots merged correctly [fraction]"), ("first_merge_s", "first correct merge [s]"),
              ("false_merges", "false merges per run"))
    for c, scene in enumerate(scenes):
        for r, (key, label) in enumerate(panels):
            ax = axes[r][c]
            for i, a in enumerate(algorithms):
                pts = sorted((s["center_error_m"], s[key]) for s in sim
                             if s["scene"] == scene and s["algorithm"] == a and s[key] is not None)
                if pts:
                    ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="osD^"[i % 4], label=a)
            ax.set_title(f"{scene}: {label}", fontsize=9)
            ax.set_xlabel("center error [m]")
            ax.set_ylim(bottom=0)
            if key == "merged_fraction":
                ax.set_ylim(0, 1.05)
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", ncol=len(algorithms))
    gs = axes[3][0].get_gridspec()
    for ax in axes[3]:
        ax.remove()
    ax = fig.add_subplot(gs[3, :])
    width = 0.8 / max(len(algorithms), 1)
    for i, a in enumerate(algorithms):
        for k, s in enumerate(sets):
            v = next((x for x in real if x["set"] == s and x["algorithm"] == a), None)
            if v is None:
                continue
            x = k + (i - (len(algorithms) - 1) / 2) * width
            n = v["pairs"]
            ax.bar(x, v["correct"] / n, width, color="tab:green")
            ax.bar(x, v["false"] / n, width, bottom=v["correct"] / n, color="tab:red")
            ax.bar(x, v["refused"] / n, width, bottom=(v["correct"] + v["false"]) / n, color="lightgrey")
            ax.text(x, 1.02, a[:8], ha="center", fontsize=7, rotation=90)
    ax.set_xticks(range(len(sets)), sets, fontsize=8)
    ax.set_ylim(0, 1.25)
    ax.set_ylabel("fraction of pairs")
    ax.set_title("real maps: pairs correct (green), false (red), refused (grey)", fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
