"""circsim.experiments.window_report (run as benchmarks/window_sweep_report.py): the center error × window table, and a clear refusal of other sweeps."""

import json
from pathlib import Path

from circsim.experiments import window_report


def report():
    return window_report


def write_rows(folder: Path, rows: list[dict]) -> Path:
    folder.mkdir()
    (folder / "runs.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


ROW = {"scenario": "scene1", "seed": 1, "center_error.magnitude_m": 0.0, "first_merge_arc_deg.Lyon": 15.0,
       "first_merge_arc_deg.mean": 15.0, "false_merges": 0, "near_180_accepted": 0, "near_180_chosen": 0,
       "final_translation_error_m.max": 0.02, "merge_cycle_ms.median": 50.0, "realtime_factor": 8.0}


def test_a_sweep_without_the_window_is_one_line_exit_2(tmp_path, capsys):
    folder = write_rows(tmp_path / "latency", [ROW])
    assert report().main([str(folder)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(folder) in err and "merger.window_m" in err, err


def test_an_empty_sweep_is_one_line_exit_2(tmp_path, capsys):
    assert report().main([str(write_rows(tmp_path / "empty", []))]) == 2
    assert "no finished run" in capsys.readouterr().err


def test_a_window_sweep_gives_its_table(tmp_path, capsys):
    rows = [{**ROW, "merger.window_m": w, "center_error.magnitude_m": e} for w in (0.0, 0.5) for e in (0.0, 0.25)]
    png = tmp_path / "window.png"
    assert report().main([str(write_rows(tmp_path / "window", rows)), "--png", str(png)]) == 0
    assert png.read_bytes()[:4] == b"\x89PNG"
    out = capsys.readouterr().out
    assert out.startswith("| scene | W (m) | center error (m) |") and "| scene1 | 0.5 | 0.25 | 1/1 |" in out


def test_a_cell_where_nothing_merged_shows_no_data_not_zero(tmp_path, capsys):
    """Issue 36 item 8: a combination where nothing merged showed "max final t error 0.0 cm" (and a cell
    without a merge cycle crashed the median)."""
    none = {**ROW, "merger.window_m": 0.0, "center_error.magnitude_m": 0.25, "first_merge_arc_deg.Lyon": None,
            "first_merge_arc_deg.mean": None, "final_translation_error_m.max": None, "merge_cycle_ms.median": None}
    rows = [{**ROW, "merger.window_m": 0.0}, none]
    assert report().main([str(write_rows(tmp_path / "w", rows)), "--png", str(tmp_path / "w.png")]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("| scene1 | 0 | 0.25 |"))
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert cells[3] == "0/1" and cells[8] == "—" and cells[9] == "—" and "0.0 cm" not in line, line


def test_plot_lines_of_equal_values_both_show(tmp_path):
    """Two windows with the same figures: each line has its own marker and x offset (one hid the other)."""
    import matplotlib.pyplot as plt

    rows = [{**ROW, "merger.window_m": w, "center_error.magnitude_m": e} for w in (0.5, 1.0) for e in (0.0, 0.25)]
    fig = window_report.plot(window_report.summarize(rows), tmp_path / "p.png")
    for ax in fig.axes:
        a, b = ax.get_lines()[:2]
        assert a.get_marker() != b.get_marker()
        assert list(a.get_xdata()) != list(b.get_xdata()) and list(a.get_ydata()) == list(b.get_ydata())
    plt.close(fig)
