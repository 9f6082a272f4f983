"""A sweep's tables: ``runs.csv`` (and ``runs.parquet``), ``summary.csv`` and the printed summary.

The contract: :func:`sweep_rows` are the finished rows of a sweep's tasks, in plan order;
:func:`summarize` groups them by the grid's values (medians and quantiles of the first-merge figures,
false merges and rates); :func:`write_tables` writes the files atomically and :func:`format_summary`
the text table a person reads. Floats are written to 12 significant digits (:mod:`circsim.record.jsonout`).
See docs/sweeps.md.
"""

from __future__ import annotations

import csv
import json
import math
import statistics
from pathlib import Path

from ..record import jsonout
from .plan import RUNS_CSV, RUNS_JSONL, RUNS_PARQUET, SUMMARY_CSV, Axis, RunTask
from .store import read_rows


def counted(n: int, singular: str, plural: str | None = None) -> str:
    """``1 seed``, ``2 seeds``: a count with its noun in the right number."""
    return f"{n} {singular if n == 1 else plural or singular + 's'}"


# --- tables ----------------------------------------------------------------------------------------
def sweep_rows(out: Path, tasks: list[RunTask]) -> list[dict]:
    """The rows of this sweep's tasks from the JSONL, in plan order (grid order, then seed)."""
    by_key = {r["run_key"]: r for r in read_rows(out / RUNS_JSONL) if "run_key" in r}
    return [by_key[t.key] for t in tasks if t.key in by_key]


def _quantiles(xs: list[float]) -> tuple[float, float, float] | tuple[None, None, None]:
    xs = sorted(x for x in xs if x is not None)
    if not xs:
        return None, None, None
    if len(xs) == 1:
        return xs[0], xs[0], xs[0]
    q = statistics.quantiles(xs, n=4, method="inclusive")
    return q[0], statistics.median(xs), q[2]


def summarize(rows: list[dict], axes: list[Axis]) -> list[dict]:
    """One line per grid combination: medians and IQRs over seeds."""
    keys = [a.key for a in axes]
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault(tuple(json.dumps(r.get(k)) for k in keys), []).append(r)
    out = []
    for g, rs in groups.items():
        s = {k: json.loads(v) for k, v in zip(keys, g, strict=True)}
        s["runs"] = len(rs)
        s["all_merged_frac"] = sum(bool(r["all_merged"]) for r in rs) / len(rs)
        for m in ("first_merge_s.mean", "first_merge_arc_deg.mean", "rejected_correct_rate",
                  "merge_cycle_ms.median", "realtime_factor", "top_error_deg.median",
                  "top_translation_error_m.median", "final_translation_error_m.max", "consensus_s",
                  "consensus_held_s"):
            q1, med, q3 = _quantiles([r.get(m) for r in rs])
            s[f"{m}.median"], s[f"{m}.q1"], s[f"{m}.q3"] = med, q1, q3
        s["false_merges.total"] = sum(r["false_merges"] for r in rs)
        s["runs_with_false_merge"] = sum(r["false_merges"] > 0 for r in rs)
        s["near_180_proposed.total"] = sum(r.get("near_180_proposed") or 0 for r in rs)
        s["near_180_accepted.total"] = sum(r.get("near_180_accepted") or 0 for r in rs)
        s["near_180_chosen.total"] = sum(r.get("near_180_chosen") or 0 for r in rs)
        s["consensus_frac"] = sum(r.get("consensus_s") is not None for r in rs) / len(rs)
        out.append(s)
    return out


def _columns(rows: list[dict]) -> list[str]:
    cols: dict[str, None] = {}
    for r in rows:
        cols.update(dict.fromkeys(r))
    return list(cols)


def write_csv(rows: list[dict], path: Path) -> None:
    """Rows as CSV: columns are the union of their keys in first-seen order; None is empty, lists and
    dicts are JSON; no rows, an empty file. Written atomically (temporary file, then rename)."""
    import io

    from merger.io.mapio import write_files

    f = io.StringIO(newline="")
    if rows:
        w = csv.DictWriter(f, fieldnames=_columns(rows), restval="")
        w.writeheader()
        for r in jsonout.rounded(rows):
            w.writerow({k: ("" if v is None else json.dumps(v) if isinstance(v, list | dict) else v)
                        for k, v in r.items()})
    write_files({path: f.getvalue().encode()})  # atomic: a reader never sees half a table


def write_tables(rows: list[dict], summary: list[dict], out: Path) -> list[Path]:
    """runs.csv and summary.csv (one row per run / per combination); runs.parquet when pyarrow is
    installed (the ``sweep`` extra). Columns are the union of all rows' keys, in first-seen order."""
    paths = [out / RUNS_CSV, out / SUMMARY_CSV]
    write_csv(rows, paths[0])
    write_csv(summary, paths[1])
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return paths
    from merger.io.mapio import write_files

    cols = _columns(rows)
    table = pa.Table.from_pylist([{c: r.get(c) for c in cols} for r in rows])
    buf = pa.BufferOutputStream()  # in memory, then written as every table: a full disk names the file
    pq.write_table(table, buf)
    write_files({out / RUNS_PARQUET: buf.getvalue().to_pybytes()})
    paths.append(out / RUNS_PARQUET)
    return paths


def _cm(v):
    return None if v is None else 100.0 * v


def format_summary(summary: list[dict], axes: list[Axis]) -> str:
    """The summary as a text table: one row per grid combination, every column under its header
    (right-aligned, as wide as its widest cell). Medians over seeds with [q1–q3]; "—" where no run
    had a value (e.g. no robot merged)."""
    def f(v, fmt="{:.1f}"):
        return "—" if v is None or (isinstance(v, float) and math.isnan(v)) else fmt.format(v)

    def iqr(s, m, fmt="{:.1f}"):
        return f"{f(s[m + '.median'], fmt)} [{f(s[m + '.q1'], fmt)}–{f(s[m + '.q3'], fmt)}]"

    columns = [(a.key, lambda s, k=a.key: json.dumps(s[k])) for a in axes] + [
        ("runs", lambda s: str(s["runs"])),
        ("all merged", lambda s: f"{s['all_merged_frac']:.0%}"),
        ("first merge s", lambda s: iqr(s, "first_merge_s.mean")),
        ("arc deg", lambda s: iqr(s, "first_merge_arc_deg.mean")),
        ("false merges", lambda s: str(s["false_merges.total"])),
        ("rej.-correct rate", lambda s: iqr(s, "rejected_correct_rate", "{:.2f}")),
        ("top err deg", lambda s: f(s["top_error_deg.median.median"])),
        ("top err cm", lambda s: f(_cm(s.get("top_translation_error_m.median.median")))),
        ("180° prop/acc", lambda s: f"{s['near_180_proposed.total']}/{s['near_180_accepted.total']}"),
        ("cycle ms", lambda s: f(s["merge_cycle_ms.median.median"], "{:.0f}")),
        ("consensus s", lambda s: iqr(s, "consensus_s")),
        ("consensus runs", lambda s: f"{s['consensus_frac']:.0%}"),
    ]
    cells = [[fmt(s) for _, fmt in columns] for s in summary]
    widths = [max([len(head)] + [len(row[i]) for row in cells]) for i, (head, _) in enumerate(columns)]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(row, widths, strict=True))
                     for row in [[head for head, _ in columns], *cells])
