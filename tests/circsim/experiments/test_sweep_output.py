"""What a sweep shows a person: the summary text table and sweep.png's axes (circsim.experiments.sweep, sweep_plot)."""

import re

from circsim.experiments.plan import parse_grid
from circsim.experiments.plots import ANGLE_TICKS, PANELS, sweep_figure
from circsim.experiments.tables import format_summary, summarize


def rows(errors=(0.0, 0.1), seeds=(1, 2, 3), angle=lambda e, s: 0.3 + 2 * e * s):
    out = []
    for e in errors:
        for s in seeds:
            merged = e == 0.0
            out.append({
                "seed": s, "center_error.magnitude_m": e, "all_merged": merged, "false_merges": 0,
                "first_merge_s.mean": 2.0 + 0.1 * s if merged else None,
                "first_merge_arc_deg.mean": 15.0 + s if merged else None,
                "rejected_correct_rate": 0.1 * s, "merge_cycle_ms.median": 60.0 + s, "realtime_factor": 8.0,
                "top_error_deg.median": angle(e, s), "top_translation_error_m.median": 0.01 + e,
                "final_translation_error_m.max": 0.02, "consensus_s": 2.5 if merged else None,
                "consensus_held_s": 40.0 if merged else None, "near_180_proposed": 3, "near_180_accepted": 0,
                "near_180_chosen": 0,
            })
    return out


def column_ends(line: str) -> list[int]:
    """Where each cell ends: cells are separated by two or more spaces (a cell may hold single spaces)."""
    return [m.end() for m in re.finditer(r"\S+(?: \S+)*", line)]


def test_summary_table_has_a_header_over_every_column():
    axes = parse_grid(["center_error=0,0.1", "network.latency=0,1"])
    rs = [{**r, "network.latency_s": lat} for r in rows() for lat in (0.0, 1.0)]
    lines = format_summary(summarize(rs, axes), axes).splitlines()
    assert len(lines) == 1 + 4
    head = column_ends(lines[0])
    assert len(head) == 2 + 12, lines[0]  # two grid keys and 12 figures, each named
    for line in lines[1:]:
        assert column_ends(line) == head, f"\n{lines[0]}\n{line}"  # right-aligned under its header
    assert lines[0].split()[-2:] == ["consensus", "runs"]  # the last column has its own header
    assert "—" in lines[-1] and "—" not in lines[1]  # no robot merged at 0.1 m: no first-merge figures, shown as a dash


def tick_labels(fig):
    """The y tick labels a reader sees (ticks inside the panel's range)."""
    fig.canvas.draw()
    out = {}
    for ax in fig.axes:
        lo, hi = ax.get_ylim()
        out[ax.get_ylabel()] = [t.get_text() for v, t in zip(ax.get_yticks(), ax.get_yticklabels(), strict=True)
                                if lo <= v <= hi and t.get_text()]
    return out


def test_sweep_plot_has_plain_ticks_and_a_range_for_constant_series():
    fig = sweep_figure(rows(angle=lambda e, s: 0.597773 * s), [], title="t")
    labels = tick_labels(fig)
    plain = re.compile(r"^\d+(\.\d+)?$")
    for name, ticks in labels.items():
        assert ticks and all(plain.match(t) for t in ticks), (name, ticks)  # never 5.97773×10⁻¹
    panels = dict(zip((m for m, _ in PANELS), fig.axes, strict=False))
    lo, hi = panels["false_merges"].get_ylim()  # 0 in every run: a range around 0, not ±0.04
    assert -0.1 < lo <= 0.0 and hi >= 1.0
    assert all(float(t).is_integer() for t in labels[panels["false_merges"].get_ylabel()])
    assert panels["all_merged"].get_ylim()[1] <= 1.1  # a fraction
    angle = labels[panels["top_error_deg.median"].get_ylabel()]
    assert {float(t) for t in angle} <= set(ANGLE_TICKS) and "2" in angle  # the 2° tolerance is a tick
    assert panels["first_merge_s.mean"].get_ylim()[0] <= 0.0  # times from 0, not a zoom on 2.1–2.3 s


def test_sweep_plot_angle_panel_reaches_a_half_turn():
    fig = sweep_figure(rows(angle=lambda e, s: 170.0 if e else 0.4), [], title="t")
    ax = fig.axes[[m for m, _ in PANELS].index("top_error_deg.median")]
    assert ax.get_ylim()[1] == 180.0
    assert "180" in tick_labels(fig)[ax.get_ylabel()]


def test_sweep_plot_lines_of_equal_values_both_show_and_no_data_has_no_point():
    """Issue 36 item 8: a line hidden behind another in two panels; a combination where no hypothesis was
    correct drew a rejected-correct rate of 0."""
    two = [{**r, "merger.window_m": w} for w in (0.5, 1.0) for r in rows()]
    for r in two:
        if r["merger.window_m"] == 1.0 and r["center_error.magnitude_m"] == 0.1:
            r["rejected_correct_rate"] = None  # nothing correct to reject: no data
    fig = sweep_figure(two, ["merger.window_m"], title="t")
    panel = dict(zip((m for m, _ in PANELS), fig.axes, strict=False))
    for metric in ("false_merges", "all_merged"):
        a, b = panel[metric].get_lines()[:2]
        assert a.get_marker() != b.get_marker() and list(a.get_xdata()) != list(b.get_xdata())
        assert list(a.get_ydata()) == list(b.get_ydata())  # equal values, both visible
    rate = [ln for ln in panel["rejected_correct_rate"].get_lines() if ln.get_label().endswith("=1.0")]
    assert len(rate) == 1 and len(rate[0].get_xdata()) == 1  # the 0.1 m point is absent, not 0


def test_sweep_rate_of_rejected_correct_is_no_data_without_a_correct_hypothesis():
    from circsim.config.scenario import bundled_scenarios, load_scenario
    from circsim.experiments.plan import RunTask
    from circsim.experiments.sweep import flatten

    sc = load_scenario(bundled_scenarios()["scene1"])
    robot = {"first_merge_s": None, "first_merge_arc_deg": None, "cycles": 12, "accepted": 0,
             "final_angle_error_deg": None, "final_translation_error_m": None}
    rec = {"scenario": "scene1", "seed": 1, "params": {}, "robots": {"A": dict(robot), "B": dict(robot)},
           "all_merged": False, "false_merges": 0, "rejected_correct": 0, "realtime_factor": 1.0, "sim_s": 1.0,
           "wall_s": 1.0, "interrupted": False, "merge_cycle_ms": {"median": 5.0, "p95": 6.0}}
    task = RunTask(raw=sc.raw, source=sc.source, grid=(), seed=1, key="k")
    row = flatten(rec, task, sc)
    assert row["cycles"] == 24 and row["rejected_correct_rate"] is None
    rec["robots"]["A"]["accepted"] = 3
    assert flatten(rec, task, sc)["rejected_correct_rate"] == 0.0
