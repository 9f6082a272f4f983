"""circsim.record.parts: a recording's temporary part is locked while its run lives; the next run of the same
output removes the parts of runs killed outright (issue 37: a SIGKILLed run left ``.NAME.rrd.*.part.rrd``)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from circsim.record.parts import claim_part, release, remove_stale_parts
from tests.subproc import wait_for

BIN = Path(sys.executable).parent


def test_a_dead_writer_s_part_goes_a_live_one_stays(tmp_path):
    target = tmp_path / "run.rrd"
    child = subprocess.Popen([sys.executable, "-c", "import sys, time; from circsim.record.parts import claim_part; "
                              f"print(claim_part({str(target)!r})[0], flush=True); time.sleep(60)"],
                             stdout=subprocess.PIPE, text=True)
    dead = Path(child.stdout.readline().strip())
    child.kill()
    child.wait()
    live, fd = claim_part(target)  # claiming removes the dead one first
    other = tmp_path / ".other.rrd.abcd.part.rrd"  # another output's part is not ours to remove
    other.write_bytes(b"")
    try:
        assert not dead.exists() and Path(live).exists()
        assert remove_stale_parts(target) == [] and Path(live).exists()  # locked: its run still writes it
    finally:
        release(fd)
    assert remove_stale_parts(target) == [Path(live)] and other.exists()


@pytest.mark.slow
def test_a_sigkilled_run_s_part_is_removed_by_the_next_run(tmp_path):
    rrd = tmp_path / "out" / "scene1.rrd"
    rrd.parent.mkdir()
    parts = lambda: sorted(rrd.parent.glob(".scene1.rrd.*.part.rrd"))  # noqa: E731
    p = subprocess.Popen([str(BIN / "circsim"), "run", "scene1", "--set", "duration_s=60", "--rrd", str(rrd),
                          "--quiet"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        wait_for(lambda: parts() and parts()[0].stat().st_size > 0, 120, "the recording's part")
    finally:
        os.kill(p.pid, signal.SIGKILL)
        p.wait()
    assert len(parts()) == 1 and not rrd.exists()
    r = subprocess.run([str(BIN / "circsim"), "run", "scene1", "--set", "duration_s=1", "--rrd", str(rrd), "--quiet"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert rrd.exists() and parts() == []
