"""circsim.experiments.plots: what each panel of sweep.png draws is the data — per swept value the median
over seeds (the fraction of runs for "every robot merged"), lines side by side within ±1.5 % of the span,
one line per other setting with its own marker, and no point where no run has a value."""

from __future__ import annotations

import numpy as np
import pytest

from circsim.experiments.plots import MARKERS, PANELS, dodge, marker, plot_sweep, sweep_figure

METRICS = [m for m, _ in PANELS]


def _rows():
    out = []
    for lat in (0.0, 1.0):
        for e in (0.0, 0.1, 0.3):
            for s in (1, 2, 3, 4):
                merged = not (e == 0.3 and lat == 1.0)
                out.append({"seed": s, "center_error.magnitude_m": e, "network.latency_s": lat,
                            "first_merge_s.mean": (1.0 + 10 * e + s + lat) if merged else None,
                            "first_merge_arc_deg.mean": 5.0 * s if merged else None,
                            "all_merged": merged and s != 4, "false_merges": s % 2,
                            "rejected_correct_rate": None, "top_error_deg.median": 0.1 * s})
    return out


def _line(fig, metric, k):
    ax = fig.axes[METRICS.index(metric)]
    return ax, ax.lines[k]


def test_each_point_is_the_median_over_seeds_and_fractions_are_means():
    rows = _rows()
    fig = sweep_figure(rows, ["network.latency_s"], title="t")
    for k, lat in enumerate((0.0, 1.0)):  # lines in label order: latency 0.0, then 1.0
        _, ln = _line(fig, "first_merge_s.mean", k)
        assert ln.get_label() == f"network.latency_s={lat}"
        want = [np.median([r["first_merge_s.mean"] for r in rows if r["network.latency_s"] == lat
                           and r["center_error.magnitude_m"] == e and r["first_merge_s.mean"] is not None])
                for e in (0.0, 0.1, 0.3) if not (e == 0.3 and lat == 1.0)]
        assert list(ln.get_ydata()) == pytest.approx(want)  # latency 1 at 0.3 m: nobody merged, no point
        assert list(ln.get_xdata()) == pytest.approx([x + dodge(k, 2, [0.0, 0.1, 0.3])
                                                      for x in (0.0, 0.1, 0.3)][:len(want)])
        assert ln.get_marker() == marker(k)
        _, frac = _line(fig, "all_merged", k)
        assert list(frac.get_ydata()) == pytest.approx([0.75, 0.75, 0.75 if lat == 0.0 else 0.0])
        _, fm = _line(fig, "false_merges", k)
        assert list(fm.get_ydata()) == pytest.approx([0.5, 0.5, 0.5])  # seeds 1..4: 1, 0, 1, 0
    ax = fig.axes[METRICS.index("rejected_correct_rate")]
    assert len(ax.lines) == 0  # no run had a value: no line at all
    assert "median and IQR over 4 seeds" in fig._suptitle.get_text()


def test_the_band_is_the_interquartile_range():
    rows = _rows()
    fig = sweep_figure(rows, [], title="")
    ax = fig.axes[METRICS.index("first_merge_arc_deg.mean")]
    band = ax.collections[0].get_paths()[0].vertices
    ys = [5.0 * s for s in (1, 2, 3, 4)]
    q1, q3 = np.percentile(ys, 25), np.percentile(ys, 75)
    assert band[:, 1].min() == pytest.approx(q1) and band[:, 1].max() == pytest.approx(q3)


@pytest.mark.parametrize("n", [2, 3, 5])
def test_lines_are_dodged_symmetrically_within_the_span(n):
    xs = [0.0, 0.2, 0.5]
    offs = [dodge(i, n, xs) for i in range(n)]
    assert sum(offs) == pytest.approx(0.0, abs=1e-12)
    assert max(abs(o) for o in offs) == pytest.approx(0.015 * 0.5)
    assert offs == sorted(offs) and len(set(offs)) == n
    assert dodge(0, 1, xs) == 0.0 and dodge(1, 2, [3.0]) == pytest.approx(0.015)  # one value: a span of 1


def test_markers_differ_between_neighbouring_lines():
    assert len(set(MARKERS)) == len(MARKERS)
    assert [marker(i) for i in range(len(MARKERS))] == list(MARKERS) and marker(len(MARKERS)) == MARKERS[0]


def test_plot_sweep_writes_a_png(tmp_path):
    p = plot_sweep(_rows(), ["network.latency_s"], tmp_path / "sub.png", title="x")
    data = p.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
