"""The `circsim` command (issue 12): SIGTERM handled as Ctrl-C, no traceback at start-up, no half or empty
output files, --save-maps feeding `merger merge`, one-line errors for the experiment commands' numbers."""

import json
import math
import os
import shlex
import signal
import subprocess
import sys
import time

import pytest
import yaml

from circsim.cli import main
from circsim.record.viewer import rerun_executable
from merger.search import angle_diff_deg
from tests.subproc import sigint_default, wait_for


@pytest.mark.slow
def test_sigterm_during_a_run_completes_the_recording_and_the_json(tmp_path):
    rrd, js = tmp_path / "t.rrd", tmp_path / "t.json"
    cmd = [sys.executable, "-m", "circsim.cli", "run", "scene1", "--set", "duration_s=60", "--rrd", str(rrd),
           "--json", str(js), "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        def grown():  # the recording is written beside t.rrd and renamed when complete (issue 26)
            parts = list(tmp_path.glob(".t.rrd.*.part.rrd"))
            return parts and parts[0].stat().st_size > 200_000

        wait_for(lambda: grown() or proc.poll() is not None, 120, "the recording to grow")
        assert proc.poll() is None, proc.communicate()
        # and grow on: ticks are being recorded (the static scene alone can pass 200 kB while the first
        # tick still compiles the SLAM's kernels on a cold cache)
        s0 = max(p.stat().st_size for p in tmp_path.glob(".t.rrd.*.part.rrd"))
        wait_for(lambda: proc.poll() is not None or
                 max((p.stat().st_size for p in tmp_path.glob(".t.rrd.*.part.rrd")), default=0) > s0 + 100_000,
                 120, "the recording to grow with the run")
        assert proc.poll() is None, proc.communicate()
        assert not js.exists()  # the JSON appears once, whole, at the end
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 143, err
    assert "Traceback" not in err and "[INTERRUPTED]" in out
    d = json.loads(js.read_text())
    assert d["interrupted"] and 0 < d["sim_s"] < 60
    v = subprocess.run([rerun_executable(), "rrd", "verify", str(rrd)], capture_output=True, text=True, timeout=120)
    assert v.returncode == 0, v.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.json", "t.rrd"]  # no temporary file left


@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
@pytest.mark.parametrize("delay_s", [0.25, 0.6])
def test_a_signal_during_start_up_is_one_line(tmp_path, sig, code, word, delay_s):
    """While the modules load (numpy, OpenCV, the merger) and the scene is built: no traceback, no file."""
    js = tmp_path / "t.json"
    cmd = [sys.executable, "-m", "circsim.cli", "run", "scene1", "--json", str(js), "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=sigint_default)
    time.sleep(delay_s)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=120)
    if "Fatal Python error: init_import_site" in err:  # so early that Python's own start-up (its site
        assert not out and not js.exists()  # module) took the signal, before any code of ours: nothing written
        return
    assert "Traceback" not in err, err
    if proc.returncode == -sig and not out and not err:  # so early that the interpreter was still starting
        assert not js.exists()  # (a loaded machine): the default action ended it, nothing was written
    elif proc.returncode == code and "scenario scene1" not in out:  # stopped before the run began
        assert err.strip() == f"circsim: {word}" and not js.exists()
    else:  # the run had begun: it stops at a tick boundary with its figures
        assert proc.returncode == code and "[INTERRUPTED]" in out, (proc.returncode, out, err)


def test_an_output_error_before_the_run_leaves_no_empty_json(tmp_path, capsys):
    js = tmp_path / "m.json"
    (tmp_path / "f").write_text("a file, not a folder")
    assert main(["run", "scene1", "--json", str(js), "--rrd", str(tmp_path / "f" / "x.rrd"), "--quiet"]) == 2
    assert "cannot write the recording" in capsys.readouterr().err
    assert not js.exists()
    assert main(["run", "scene1", "--json", str(tmp_path), "--quiet"]) == 2  # a folder named as the JSON
    assert "a folder has that name" in capsys.readouterr().err


def test_empty_scenario_file_is_one_line_exit_2(tmp_path, capsys):
    (tmp_path / "empty.yaml").write_text("# nothing yet\n")
    assert main(["run", str(tmp_path / "empty.yaml"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "empty.yaml: empty scenario" in err


@pytest.mark.slow
def test_save_maps_feed_merger_merge(tmp_path, capsys):
    """`circsim run --save-maps DIR`: each robot's last map as map_server files and centers.yaml whose
    merge command, run as is, finds the run's ground truth."""
    from merger.cli import main as merger_main

    d = tmp_path / "maps"
    assert main(["run", "scene1", "--set", "duration_s=30", "--set", "center_error.magnitude_m=0.1",
                 "--set", "merger.window_m=0.3", "--save-maps", str(d), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert f"centers.yaml in {d}" in out
    doc = yaml.safe_load((d / "centers.yaml").read_text())
    names = list(doc["maps"])
    assert names == ["Lyon", "Auckland", "Nevers"] and doc["truth_onto"] == "Lyon"
    assert sorted(p.name for p in d.iterdir()) == sorted([f"{n}{s}" for n in names for s in (".yaml", ".pgm")]
                                                         + ["centers.yaml"])
    for m in doc["maps"].values():
        assert math.dist(m["center"], m["center_true"]) == pytest.approx(0.1, abs=1e-6)  # the center error
    argv = shlex.split(doc["merge_command"])
    assert argv[:2] == ["merger", "merge"] and "--window" in argv
    assert merger_main([*argv[1:], "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    for n, t in doc["truth"].items():
        assert abs(angle_diff_deg(res["chosen"]["theta_deg"][n], t["theta_deg"])) <= 2.0
        assert math.dist(res["chosen"]["translation_m"][n], t["translation_m"]) <= 0.1
    assert (d / "merged.yaml").exists()


def test_save_maps_into_a_file_is_refused_before_the_run(tmp_path, capsys):
    (tmp_path / "f").write_text("x")
    assert main(["run", "scene1", "--save-maps", str(tmp_path / "f"), "--quiet"]) == 2
    err = capsys.readouterr()
    assert "--save-maps" in err.err and "cannot write" in err.err and err.out == ""


@pytest.mark.parametrize("args, needle", [
    (["--step-deg", "nan"], "--step-deg: expected a number of degrees in (0, 180], got nan"),
    (["--step-deg", "0"], "--step-deg"),
    (["--max-deg", "0"], "--max-deg: expected a number of degrees in (0, 180], got 0"),
    (["--max-deg", "-5"], "--max-deg"),
    (["--max-deg", "inf"], "--max-deg"),
    (["--max-deg", "2", "--step-deg", "5"], "--step-deg: expected at most --max-deg (2), got 5"),
    (["--score-min", "nan"], "--score-min: expected an NCC coefficient in [-1, 1], got nan"),
    (["--score-min", "2"], "--score-min"),
    (["--scans-per-pose", "0"], "--scans-per-pose"),
])
def test_offline_numbers_are_checked(tmp_path, capsys, args, needle):
    assert main(["offline", "scene1", "--out", str(tmp_path / "o"), "--quiet", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err, err
    assert not (tmp_path / "o").exists()


def test_sigterm_handler_is_restored_after_main(capsys):
    before = signal.getsignal(signal.SIGTERM)
    main(["scenarios"])
    capsys.readouterr()
    assert signal.getsignal(signal.SIGTERM) is before
    assert os.getpid()  # the test process itself was not touched


def test_scenarios_show_prints_every_key_and_loads_back(capsys):
    from circsim.config.scenario import bundled_scenarios, load_scenario, scenario_from_dict

    assert main(["scenarios", "--show", "scene1"]) == 0
    text = capsys.readouterr().out
    data = yaml.safe_load(text)
    sc = load_scenario(bundled_scenarios()["scene1"])
    assert scenario_from_dict(data) == sc
    for key in ("laser", "slam", "network", "merger", "output", "center_error"):
        assert key in data
    assert data["merger"]["window_m"] == 0 and "nu_min" in data["merger"] and "drift" in data["slam"]


@pytest.mark.parametrize("assignment, path, value", [
    ("center_error=0.05", ("center_error", "magnitude_m"), 0.05),
    ("latency=0.5", ("network", "latency_s"), 0.5),
    ("network.jitter=0.1", ("network", "jitter_s"), 0.1),
    ("center_error={magnitude_m: 0.2}", ("center_error", "magnitude_m"), 0.2),  # the section itself
])
def test_set_accepts_the_grid_aliases(assignment, path, value):
    from circsim.config.scenario import bundled_scenarios, load_scenario

    sc = load_scenario(bundled_scenarios()["scene1"]).with_overrides([assignment])
    assert getattr(getattr(sc, path[0]), path[1]) == value
