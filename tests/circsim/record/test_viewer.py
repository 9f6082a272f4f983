"""circsim.record.viewer: a recording written with rerun's SDK reads back row by row (entity, time, step,
values; static rows first); a missing, foreign or empty file is one ValueError line naming it; without a
display the native viewer is not started and the web viewer is offered; ``--web`` serves on 127.0.0.1;
Ctrl-C stops the viewer and answers 130."""

from __future__ import annotations

import uuid

import pytest
import rerun as rr

from circsim.record import viewer
from circsim.record.viewer import check_rrd, has_display, read_recording, view


@pytest.fixture(scope="module")
def rrd(tmp_path_factory):
    p = tmp_path_factory.mktemp("rec") / "run.rrd"
    rec = rr.RecordingStream("circsim-test", recording_id=str(uuid.uuid4()))
    rec.save(str(p))
    rec.log("run/info", rr.TextDocument("hello"), static=True)
    for step, (t, v) in enumerate([(0.5, 1.0), (1.0, 2.5), (1.5, -3.0)]):
        rec.set_time("sim_time", duration=t)
        rec.set_time("step", sequence=step)
        rec.log("plots/Lyon/nu", rr.Scalars(v))
    rec.set_time("sim_time", duration=2.0)
    rec.set_time("step", sequence=3)
    rec.log("events/Lyon", rr.TextLog("merged", level="INFO"))
    rec.flush()
    rec.disconnect()
    return p


def test_a_recording_reads_back_row_by_row(rrd):
    rows = read_recording(rrd)
    nu = rows["/plots/Lyon/nu"]
    assert [(r["sim_time"], r["step"], r["Scalars:scalars"]) for r in nu] == \
        [(0.5, 0, [1.0]), (1.0, 1, [2.5]), (1.5, 2, [-3.0])]
    assert all(not r["static"] for r in nu)
    ev = rows["/events/Lyon"]
    assert len(ev) == 1 and ev[0]["TextLog:text"] == ["merged"] and ev[0]["sim_time"] == 2.0
    info = rows["/run/info"]
    assert info[0]["static"] and info[0]["TextDocument:text"] == ["hello"] and info[0]["sim_time"] is None


def test_files_that_are_not_recordings_are_one_line(tmp_path, rrd):
    assert check_rrd(rrd) == rrd
    with pytest.raises(ValueError, match=r"nope.rrd: no such file$"):
        check_rrd(tmp_path / "nope.rrd")
    (tmp_path / "d.rrd").mkdir()
    with pytest.raises(ValueError, match=r"d.rrd: not a file$"):
        check_rrd(tmp_path / "d.rrd")
    (tmp_path / "x.txt").write_bytes(rrd.read_bytes())
    with pytest.raises(ValueError, match=r"x.txt: not a rerun recording \(expected a .rrd file\)$"):
        check_rrd(tmp_path / "x.txt")
    (tmp_path / "e.rrd").write_bytes(b"")
    with pytest.raises(ValueError, match=r"e.rrd: not a rerun recording \(empty file\)$"):
        check_rrd(tmp_path / "e.rrd")
    (tmp_path / "j.rrd").write_bytes(b"{}\n")
    with pytest.raises(ValueError, match=r"j.rrd: not a rerun recording \(unknown header\)$"):
        read_recording(tmp_path / "j.rrd")


@pytest.mark.parametrize("env, want", [({}, False), ({"DISPLAY": ":0"}, True), ({"WAYLAND_DISPLAY": "w"}, True),
                                       ({"DISPLAY": ""}, False)])
def test_a_display_is_display_or_wayland(monkeypatch, env, want):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    for k, v in env.items():
        monkeypatch.setenv(k, v)
    monkeypatch.setattr(viewer.sys, "platform", "linux")
    assert has_display() is want


class FakeViewer:
    """A viewer process: records its command; ``wait`` answers ``code`` or raises Ctrl-C once."""

    calls: list = []

    def __init__(self, cmd, interrupt=False):
        self.cmd, self.interrupt, self.terminated = cmd, interrupt, False
        FakeViewer.calls.append(self)

    def wait(self, timeout=None):
        if self.interrupt and not self.terminated:
            raise KeyboardInterrupt
        return 0

    def terminate(self):
        self.terminated = True

    def kill(self):  # pragma: no cover - terminate suffices here
        self.terminated = True


def test_without_a_display_the_web_viewer_is_offered(monkeypatch, rrd, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(viewer.sys, "platform", "linux")
    FakeViewer.calls = []
    monkeypatch.setattr(viewer.subprocess, "Popen", FakeViewer)
    assert view(rrd) == 1
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and f"circsim view {rrd} --web" in out
    assert FakeViewer.calls == []  # no native viewer started


def test_the_web_viewer_binds_to_localhost_and_ctrl_c_answers_130(monkeypatch, rrd, capsys):
    FakeViewer.calls = []
    monkeypatch.setattr(viewer.subprocess, "Popen", FakeViewer)
    assert view(rrd, web=True, web_port=9191, grpc_port=9877) == 0
    cmd = FakeViewer.calls[0].cmd
    assert cmd[0] == viewer.rerun_executable() and cmd[1:3] == ["--serve-web", str(rrd)]
    assert cmd[cmd.index("--bind") + 1] == "127.0.0.1" and cmd[cmd.index("--web-viewer-port") + 1] == "9191"
    assert cmd[cmd.index("--port") + 1] == "9877"
    assert "http://127.0.0.1:9191" in capsys.readouterr().out
    monkeypatch.setattr(viewer.subprocess, "Popen", lambda cmd: FakeViewer(cmd, interrupt=True))
    assert view(rrd, web=True) == 130
    assert FakeViewer.calls[-1].terminated
