"""Hostile inputs, round 3 (issue 37, item 7): the command lines' small rough edges, each refused or reported
in one line naming what it concerns. (Items 1–3, 5 and 6 are tested beside their modules:
tests/merger/test_jit.py, tests/circsim/config/test_scenario.py, tests/merger/io/test_mapio.py,
tests/circsim/record/test_parts.py, tests/circsim/experiments/test_sweep.py.)"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from merger.grid import OCCUPIED_S, OccupancyGrid
from merger.io.mapio import save_map
from tests.paths import REAL_MAP
from tests.test_hostile_inputs import one_line_error

BIN = Path(sys.executable).parent


def run(cmd, env_extra=None, timeout=120):
    env = {**os.environ, **(env_extra or {})}
    p = subprocess.run([str(BIN / cmd[0]), *cmd[1:]], capture_output=True, text=True, env=env, timeout=timeout)
    return p.returncode, p.stdout, p.stderr


def test_demo_on_a_map_without_free_cells_names_the_file(tmp_path):
    """It said "the map has no free cell" without naming the map."""
    path = save_map(OccupancyGrid(np.full((80, 80), OCCUPIED_S, np.uint8), 0.05, (0.0, 0.0)), tmp_path / "wall")[0]
    code, _, err = run(["merger", "demo", "--real", str(path), "-o", str(tmp_path / "out")])
    assert code == 2
    one_line_error(err, "merger", "--real", str(path), "no free cell")
    assert not (tmp_path / "out.yaml").exists()


@pytest.mark.parametrize("value", ["abc", "0", "-1"])
@pytest.mark.parametrize("cmd", [["merger", "align", str(REAL_MAP), str(REAL_MAP), "--center", "0,0"],
                                 ["circsim", "run", "scene1", "--set", "duration_s=1"]])
def test_merger_threads_that_is_not_a_count_is_refused_before_any_work(cmd, value):
    """``MERGER_THREADS=abc`` silently meant every core."""
    code, out, err = run(cmd, {"MERGER_THREADS": value})
    assert code == 2 and out == ""
    one_line_error(err, cmd[0], "MERGER_THREADS", repr(value), "an integer >= 1")


def test_a_robot_name_with_a_newline_is_refused():
    """A newline in a robot name broke the summary table's rows."""
    code, out, err = run(["circsim", "run", "scene1", "--set", 'robots.names=["Ly\\non", "B", "C"]'])
    assert code == 2 and out == ""
    one_line_error(err, "circsim", "robots.names[0]", "control character")


def test_sweep_tables_on_a_full_disk_name_the_file(tmp_path):
    """runs.parquet was written by pyarrow straight to its file: a full disk said ``error: : No space left``
    (pyarrow's OSError names no file). Files are capped here (EFBIG, as ENOSPC): the CSV tables fit, the
    parquet table does not."""
    pytest.importorskip("pyarrow", reason="runs.parquet is written only with pyarrow (the sweep extra)")
    code = """
import resource, signal, sys
from pathlib import Path
from circsim.experiments.tables import write_tables
from merger.io.mapread import MapFileError
rows = [{f"col{c}": c * 0.5 for c in range(30)}]  # CSV ~0.3 kB, parquet ~9 kB (its metadata)
out = Path(sys.argv[1])
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
resource.setrlimit(resource.RLIMIT_FSIZE, (2000, 2000))
try:
    write_tables(rows, rows[:1], out)
except MapFileError as e:
    print(e)
"""
    p = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stdout.startswith(f"{tmp_path / 'runs.parquet'}: cannot write ("), p.stdout
    assert (tmp_path / "runs.csv").exists() and not list(tmp_path.glob(".*part*"))


def test_an_interrupted_merge_ends_without_waiting_for_the_running_searches():
    """Ctrl-C printed `merger: interrupted` at once but the process then waited for the merge pool's threads
    to finish their searches (compiled, uninterruptible: 26 s on three 4224² maps). Here a pool thread is
    busy for 60 s when the interrupt comes."""
    import time

    code = """
import sys, time
import merger.cli as C
from merger.team.pool import _pool

def busy_merge(args):
    _pool().submit(time.sleep, 60)  # a search that will not stop
    time.sleep(0.3)
    raise KeyboardInterrupt
C.cmd_merge = busy_merge
sys.argv = ["merger", "merge", "a.yaml", "b.yaml", "--center", "0,0", "-o", "x"]
sys.exit(C.main())
"""
    t0 = time.monotonic()
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=50,
                       env={**os.environ, "MERGER_THREADS": "2"})
    assert (p.returncode, p.stderr.strip()) == (130, "merger: interrupted"), p.stderr
    assert time.monotonic() - t0 < 30
