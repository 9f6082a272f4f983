"""Report of a sweep over generated floor plans (issue 44): per center error, the first merges, false merges
by kind (gross / other / drift-limited) and the refused-correct rate, as a Markdown table and a PNG.

Run from the repository root on the folder of a ``circsim sweep`` over ``world.generate.seed`` and
``center_error``::

    circsim sweep floorplan --grid world.generate.seed=$(seq -s, 0 49) --grid center_error=0,0.15,0.3 \\
        --set duration_s=30 --workers 1 --out runs/floorplan-sweep
    python benchmarks/floorplan_sweep_report.py runs/floorplan-sweep --png docs/img/floorplan_sweep.png

Reads ``runs.jsonl`` (one row per run: ``gross_merges``, ``drift_limited_merges``, ``false_merges``,
``first_merge_s.*``, ``rejected_correct_rate``, ``world.generate.seed``, ``world.center.x/y``). Prints the
table, then every run with a gross or other false merge (plan seed, center error, counts), so that none
hides in a median.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path


def load(folder: Path) -> list[dict]:
    rows = [json.loads(line) for line in (folder / "runs.jsonl").read_text().splitlines() if line.strip()]
    if not rows:
        sys.exit(f"floorplan_sweep_report: error: {folder}/runs.jsonl: no runs")
    return rows


def quartiles(xs: list[float]) -> str:
    if not xs:
        return "—"
    if len(xs) == 1:
        return f"{xs[0]:.1f}"
    q1, q2, q3 = statistics.quantiles(xs, n=4, method="inclusive")
    return f"{q2:.1f} [{q1:.1f}–{q3:.1f}]"


def kinds(r: dict) -> tuple[int, int, int]:
    g, d = r.get("gross_merges") or 0, r.get("drift_limited_merges") or 0
    return g, r["false_merges"] - g - d, d


def table(rows: list[dict]) -> str:
    errs = sorted({r["center_error.magnitude_m"] for r in rows})
    out = ["| center error m | runs | every robot merged | first merge s, median [q1–q3] (robots' mean) | "
           "slowest robot s, median / max | false merges gross / other / drift-limited (runs with any) | "
           "refused-correct rate, median [q1–q3] |", "|---|---|---|---|---|---|---|"]
    for e in errs:
        rs = [r for r in rows if r["center_error.magnitude_m"] == e]
        firsts = [r["first_merge_s.mean"] for r in rs if r["first_merge_s.mean"] is not None]
        slow = [r["first_merge_s.max"] for r in rs if r["first_merge_s.max"] is not None]
        k = [kinds(r) for r in rs]
        tot = [sum(x[i] for x in k) for i in range(3)]
        anyk = [sum(1 for x in k if x[i]) for i in range(3)]
        rate = [r["rejected_correct_rate"] for r in rs if r["rejected_correct_rate"] is not None]
        slowest = f"{statistics.median(slow):.1f} / {max(slow):.1f}" if slow else "—"
        rate_s = quartiles([100 * x for x in rate]) + (" %" if rate else "")
        out.append(f"| {e:g} | {len(rs)} | {sum(bool(r['all_merged']) for r in rs)} | {quartiles(firsts)} | "
                   f"{slowest} | {tot[0]} / {tot[1]} / {tot[2]} ({anyk[0]} / {anyk[1]} / {anyk[2]}) | {rate_s} |")
    return "\n".join(out)


def notable(rows: list[dict]) -> list[str]:
    lines = []
    for r in sorted(rows, key=lambda r: (r["center_error.magnitude_m"], r["world.generate.seed"])):
        g, o, d = kinds(r)
        if g or o or not r["all_merged"]:
            lines.append(f"plan seed {int(r['world.generate.seed'])}, center error {r['center_error.magnitude_m']:g} m: "
                         f"gross {g}, other {o}, drift-limited {d}, every robot merged: {r['all_merged']}, "
                         f"robots merged {r['robots_merged']}")
    return lines


def plot(rows: list[dict], png: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    errs = sorted({r["center_error.magnitude_m"] for r in rows})
    fig, ax = plt.subplots(1, 3, figsize=(13, 3.8))
    data = [[r["first_merge_s.mean"] for r in rows if r["center_error.magnitude_m"] == e
             and r["first_merge_s.mean"] is not None] for e in errs]
    ax[0].boxplot(data, whis=(0, 100))
    ax[0].set_xticks(range(1, len(errs) + 1), [f"{e:g}" for e in errs])
    ax[0].set(title="first correct merge (robots' mean), per plan", xlabel="center error (m)", ylabel="s", ylim=(0, None))
    bottom = [0.0] * len(errs)
    for i, (name, col) in enumerate([("gross", "tab:red"), ("other", "tab:orange"), ("drift-limited", "tab:gray")]):
        v = [sum(kinds(r)[i] for r in rows if r["center_error.magnitude_m"] == e) /
             max(1, sum(r["center_error.magnitude_m"] == e for r in rows)) for e in errs]
        ax[1].bar(range(len(errs)), v, bottom=bottom, color=col, label=name)
        bottom = [b + x for b, x in zip(bottom, v, strict=True)]
    ax[1].set_xticks(range(len(errs)), [f"{e:g}" for e in errs])
    ax[1].set(title="false merges per run, by kind", xlabel="center error (m)", ylabel="per run")
    ax[1].legend(frameon=False)
    rates = [[100 * r["rejected_correct_rate"] for r in rows if r["center_error.magnitude_m"] == e
              and r["rejected_correct_rate"] is not None] for e in errs]
    ax[2].boxplot(rates, whis=(0, 100))
    ax[2].set_xticks(range(1, len(errs) + 1), [f"{e:g}" for e in errs])
    ax[2].set(title="refused-correct cycles, per plan", xlabel="center error (m)", ylabel="% of cycles", ylim=(0, None))
    n = len({r["world.generate.seed"] for r in rows})
    fig.suptitle(f"{n} generated floor plans × center error, 4 robots, defaults, "
                 f"{rows[0]['duration_s']:g} s simulated")
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("folder", type=Path)
    p.add_argument("--png", type=Path)
    a = p.parse_args(argv)
    rows = load(a.folder)
    print(table(rows))
    for line in notable(rows):
        print(line)
    wall = [r["wall_s"] for r in rows]
    print(f"{len(rows)} runs, wall time per run median {statistics.median(wall):.1f} s, max {max(wall):.1f} s, "
          f"sum {sum(wall) / 60:.1f} min")
    if a.png:
        plot(rows, a.png)
        print(f"plot: {a.png}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
