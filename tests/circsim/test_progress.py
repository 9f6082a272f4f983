"""circsim.progress: long work shows progress on stderr when it is not a terminal too (issue 36 item 9)."""

import io

from circsim import progress
from circsim.progress import PlainProgress, progress_bar


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_plain_lines_at_most_every_few_seconds_and_one_at_the_end():
    clock, out = Clock(), io.StringIO()
    bar = PlainProgress(60, "sim s", "scene1", every_s=5.0, file=out, clock=clock)
    for step in range(1, 601):  # 60 simulated seconds in 0.1 s ticks, 0.05 s of wall time each
        clock.t = 0.05 * step
        bar.n = round(0.1 * step, 1)
        bar.refresh()
    bar.close()
    lines = out.getvalue().splitlines()
    assert len(lines) == 30 // 5 + 1  # one per 5 s of the 30 s of work, and the last
    assert lines[0] == "circsim: scene1 10/60 sim s (17%), 5 s elapsed"
    assert lines[-1] == "circsim: scene1 60/60 sim s (100%), 30 s elapsed"


def test_short_work_prints_nothing_and_postfix_and_write_pass_through():
    clock, out = Clock(), io.StringIO()
    with PlainProgress(3, "run", "sweep", file=out, clock=clock) as bar:
        bar.update(1)
        bar.set_postfix_str("scene1 seed 2")
        clock.t = 6.0
        bar.update(1)
        bar.write("circsim: run {} seed 1 failed: boom")
    assert out.getvalue().splitlines() == ["circsim: sweep 2/3 run (67%), 6 s elapsed, scene1 seed 2",
                                           "circsim: run {} seed 1 failed: boom",
                                           "circsim: sweep 2/3 run (67%), 6 s elapsed, scene1 seed 2"]
    quiet = io.StringIO()
    with PlainProgress(3, "run", "sweep", file=quiet, clock=Clock()) as bar:
        bar.update(3)
    assert quiet.getvalue() == ""


def test_progress_bar_chooses_by_terminal_and_quiet(monkeypatch):
    from tqdm import tqdm

    class Tty(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setattr("sys.stderr", io.StringIO())
    assert isinstance(progress_bar(5, "run", "sweep", quiet=False), PlainProgress)
    q = progress_bar(5, "run", "sweep", quiet=True)
    assert isinstance(q, tqdm) and q.disable
    monkeypatch.setattr("sys.stderr", Tty())
    t = progress_bar(5, "run", "sweep", quiet=False)
    assert isinstance(t, tqdm) and not t.disable
    t.close()


def test_circsim_run_prints_progress_lines_to_stderr_unless_quiet(monkeypatch, capsys):
    from circsim.cli import main

    monkeypatch.setattr(progress, "PLAIN_EVERY_S", 0.0)  # every tick's refresh prints
    assert main(["run", "scene1", "--set", "duration_s=2"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err and all(line.startswith("circsim: scene1 ") and "/2 sim s (" in line for line in err), err
    assert err[-1].startswith("circsim: scene1 2/2 sim s (100%)")
    assert main(["run", "scene1", "--set", "duration_s=2", "--quiet"]) == 0
    assert capsys.readouterr().err == ""
