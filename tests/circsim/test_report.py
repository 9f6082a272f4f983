"""circsim run --png (circsim/report.py): a static picture of one run — the last merged map, ν over time with
false merges marked, the first merges — written after the run, checked before it like every output."""

from __future__ import annotations

import cv2
import numpy as np

from circsim.cli import main
from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.report import RunReport
from circsim.sim import Simulation


def test_the_report_holds_every_cycle_and_the_last_merge():
    sc = load_scenario(bundled_scenarios()["scene1"]).with_overrides(["duration_s=4"])
    report = RunReport()
    res = Simulation(sc, [report]).run()
    assert report.names == list(sc.robots.names)
    for n, r in res.robots.items():
        rows = report.cycles[n]
        assert sum(acc for _, _, acc, _ in rows) == r.accepted and sum(f for *_, f in rows) == r.false_merges
        assert all(0.0 <= nu <= 1.0 for _, nu, _, _ in rows if nu == nu)
    assert set(report.last) == {n for n, r in res.robots.items() if r.accepted}
    img = cv2.imdecode(np.frombuffer(report.png(), np.uint8), cv2.IMREAD_COLOR)
    assert img is not None and img.shape[1] > 1000 and img.shape[0] > 400
    assert (img.std(axis=(0, 1)) > 10).all()  # a picture, not a blank page


def test_run_writes_the_report_and_refuses_a_clash_before_the_run(tmp_path, capsys):
    png = tmp_path / "r" / "report.png"
    assert main(["run", "scene1", "--set", "duration_s=3", "--quiet", "--png", str(png)]) == 0
    assert f"report:    {png}" in capsys.readouterr().out
    assert cv2.imread(str(png)) is not None
    clash = tmp_path / "same.out"
    assert main(["run", "scene1", "--set", "duration_s=3", "--quiet", "--png", str(clash), "--json", str(clash)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and ("--png" in err[0] or "--json" in err[0]), err
    assert not clash.exists()
