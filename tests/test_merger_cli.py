"""The `merger` command: align and merge real files, JSON output, one-line errors with exit code 2."""

import json
import subprocess
import sys

import pytest

from merger.cli import main
from merger.mapio import save_map

from .conftest import three_views


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    d = tmp_path_factory.mktemp("maps")
    _, names, maps, truth = three_views(5)
    paths, centers = [], []
    for n, (g, c) in zip(names, maps, strict=True):
        y, _ = save_map(g, d / f"{n}.yaml")
        paths.append(y)
        centers.append(f"{c[0]:.6f},{c[1]:.6f}")
    return d, paths, centers, truth


def test_align_json(saved, capsys):
    d, paths, centers, truth = saved
    rc = main(["align", str(paths[0]), str(paths[1]), "--center", centers[0], "--center-moving", centers[1],
               "--json", "--method", "reference"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0
    assert abs((out["theta_deg"] - truth["Auckland"] + 180) % 360 - 180) <= 1.0
    for k in ("score", "runner_up_deg", "verification"):
        assert k in out
    assert out["verification"]["accepted"] and out["verification"]["support"] >= 150


def test_merge_writes_map_and_overlay(saved, capsys):
    d, paths, centers, truth = saved
    out = d / "merged"
    rc = main(["merge", *map(str, paths), *sum((["--center", c] for c in centers), []), "-o", str(out)])
    text = capsys.readouterr().out
    assert rc == 0, text
    assert (d / "merged.yaml").exists() and (d / "merged.pgm").exists() and (d / "merged_overlay.png").exists()
    assert "chosen" in text


@pytest.mark.parametrize("args, needle", [
    (["align", "nope.yaml", "nope2.yaml", "--center", "0,0"], "nope.yaml"),
    (["align", "{p0}", "{p1}", "--center", "abc"], "--center"),
    (["merge", "{p0}", "{p1}", "--center", "0,0", "--center", "1,1", "--center", "2,2", "-o", "x"], "--center"),
    (["align", "{p0}"], "required"),
    (["align", "{p0}", "{p1}", "--center", "0,0", "--roi", "-3"], "--roi"),
])
def test_user_errors_one_line_exit_2(saved, args, needle):
    d, paths, _, _ = saved
    args = [a.format(p0=paths[0], p1=paths[1]) for a in args]
    r = subprocess.run([sys.executable, "-m", "merger.cli", *args], capture_output=True, text=True, cwd=d)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and needle in r.stderr and "Traceback" not in r.stderr


def test_demo_runs(tmp_path, capsys):
    rc = main(["demo", "-o", str(tmp_path), "--method", "reference"])
    text = capsys.readouterr().out
    assert rc == 0 and "angle errors" in text
    assert (tmp_path / "merged_overlay.png").exists()
