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


@pytest.mark.parametrize("name", ["merged", "merged.yaml"])
def test_merge_writes_map_and_overlay(saved, capsys, name, tmp_path):
    d, paths, centers, truth = saved
    rc = main(["merge", *map(str, paths), *sum((["--center", c] for c in centers), []), "-o", str(tmp_path / name)])
    text = capsys.readouterr().out
    assert rc == 0, text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["merged.pgm", "merged.yaml", "merged_overlay.png"]
    assert "chosen" in text


@pytest.mark.parametrize("args, needle", [
    (["align", "nope.yaml", "nope2.yaml", "--center", "0,0"], "nope.yaml"),
    (["align", "{p0}", "{p1}", "--center", "abc"], "--center"),
    (["merge", "{p0}", "{p1}", "--center", "0,0", "--center", "1,1", "--center", "2,2", "-o", "x"], "--center"),
    (["align", "{p0}"], "required"),
    (["align", "{p0}", "{p1}", "--center", "0,0", "--roi", "-3"], "--roi"),
    (["merge", "{p0}", "{p1}", "--center", "0,0", "-o", "{p0}/out"], "cannot write"),  # a file, not a folder
    (["demo", "-o", "{p0}/x"], "cannot write"),
])
def test_user_errors_one_line_exit_2(saved, args, needle):
    d, paths, _, _ = saved
    args = [a.format(p0=paths[0], p1=paths[1]) for a in args]
    r = subprocess.run([sys.executable, "-m", "merger.cli", *args], capture_output=True, text=True, cwd=d)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and needle in r.stderr and "Traceback" not in r.stderr


def test_corrupt_image_is_one_line(tmp_path):
    """OpenCV's own log line about an unreadable image is silenced: the user sees our one line."""
    (tmp_path / "g.pgm").write_bytes(b"P5\n10 10\n255\nxx")
    (tmp_path / "g.yaml").write_text("image: g.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n"
                                     "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    r = subprocess.run([sys.executable, "-m", "merger.cli", "align", "g.yaml", "g.yaml", "--center", "0,0"],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "g.pgm: not a readable image" in r.stderr, r.stderr


def test_demo_runs(tmp_path, capsys):
    rc = main(["demo", "-o", str(tmp_path), "--method", "reference"])
    text = capsys.readouterr().out
    assert rc == 0 and "angle errors" in text
    assert (tmp_path / "merged_overlay.png").exists()
