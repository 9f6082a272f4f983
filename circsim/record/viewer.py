"""Opening and reading recorded runs: ``circsim view RUN.rrd [--web]`` and :func:`read_recording`.

The contract: :func:`view` opens a complete ``.rrd`` in the viewer shipped with rerun-sdk
(:func:`rerun_executable`; ``--web`` serves the web viewer on 127.0.0.1 instead, and without a display
that is the only choice); a missing, foreign or empty file is one :class:`ValueError` line
(:func:`check_rrd`). :func:`read_recording` reads a recording back with rerun's own chunk reader,
entity path → rows (the tests read what the recorder wrote with it). The entity tree is described in
:mod:`circsim.record.rerun`.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np


# --- viewing and reading recordings ------------------------------------------------------------------
def rerun_executable() -> str:
    """The native ``rerun`` viewer/CLI shipped in the rerun-sdk wheel (package ``rerun_cli``)."""
    exe = "rerun.exe" if sys.platform.startswith("win") else "rerun"
    candidates = []
    try:
        import rerun_cli

        d = Path(rerun_cli.__file__).parent
        candidates += [d / "Rerun.app" / "Contents" / "MacOS" / "Rerun", d / exe]
    except ImportError:  # pragma: no cover - rerun-sdk always ships it
        pass
    candidates += [Path(sys.executable).parent / exe]
    for c in candidates:
        if c.is_file():
            return str(c)
    found = shutil.which("rerun")
    if found:
        return found
    raise RuntimeError("the rerun viewer executable was not found; install rerun-sdk (pip install rerun-sdk)")


def has_display() -> bool:
    """Whether a native window can open: on Linux/BSD, ``$DISPLAY`` or ``$WAYLAND_DISPLAY`` is set."""
    if sys.platform.startswith(("win", "darwin")):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def check_rrd(path) -> Path:
    """``path`` as a Path if it is a readable rerun recording, else ValueError naming the file and problem."""
    p = Path(path)
    if not p.exists():
        raise ValueError(f"{p}: no such file")
    if not p.is_file():
        raise ValueError(f"{p}: not a file")
    if p.suffix != ".rrd":
        raise ValueError(f"{p}: not a rerun recording (expected a .rrd file)")
    with p.open("rb") as f:
        head = f.read(4)
    if not head.startswith(b"RRF"):
        raise ValueError(f"{p}: not a rerun recording ({'empty file' if not head else 'unknown header'})")
    return p


def view(path, *, web: bool = False, web_port: int = 9090, grpc_port: int = 9876) -> int:
    """Open a recorded run in the rerun viewer; returns an exit code (``circsim view RUN.rrd [--web]``).

    Native viewer by default. Without a display (Linux without ``$DISPLAY``/``$WAYLAND_DISPLAY``) it prints
    one line offering the web viewer and returns 1. ``web=True`` serves the web viewer bound to 127.0.0.1
    (``rerun --serve-web RUN.rrd --bind 127.0.0.1``; browse http://127.0.0.1:9090) until Ctrl-C (returns 130).
    Raises ValueError for a missing file or one that is not an .rrd recording.
    """
    p = check_rrd(path)
    exe = rerun_executable()
    if web:
        print(f"circsim view: serving {p} at http://127.0.0.1:{web_port} (Ctrl-C to stop)", flush=True)
        return _run([exe, "--serve-web", str(p), "--bind", "127.0.0.1", "--web-viewer-port", str(web_port),
                     "--port", str(grpc_port)])
    if not has_display():
        print(f"circsim view: no display ($DISPLAY/$WAYLAND_DISPLAY unset); use the web viewer: "
              f"circsim view {p} --web  (= rerun --serve-web {p} --bind 127.0.0.1, then open http://127.0.0.1:9090)")
        return 1
    return _run([exe, str(p)])


def _run(cmd: list[str]) -> int:
    proc = subprocess.Popen(cmd)
    try:
        return proc.wait()
    except KeyboardInterrupt:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        return 130


def read_recording(path) -> dict[str, list[dict]]:
    """Every logged row of a recording, by entity path, read with rerun's own reader (``rerun.chunk``).

    Returns ``{entity_path: [row, ...]}`` with rerun's paths (leading ``/``, e.g. ``/events/Lyon``). A row
    is a dict: ``static`` (bool), ``sim_time`` (float s or None), ``step`` (int or None) and one entry per
    component, keyed ``"Archetype:field"`` (``"Scalars:scalars"``, ``"TextLog:text"``, ...), holding the
    logged batch as a list (blobs such as ``GridMap:data`` as uint8 arrays). Rows are in (static, step,
    sim_time) order. Works on files without a footer too (e.g. a killed process).
    """
    from rerun.chunk import RrdReader

    p = check_rrd(path)
    out: dict[str, list[dict]] = {}
    for chunk in RrdReader(str(p)).stream():
        rb = chunk.to_record_batch()
        n = rb.num_rows
        rows = [{"static": chunk.is_static, "sim_time": None, "step": None} for _ in range(n)]
        for name, col in zip(rb.schema.names, rb.columns, strict=True):
            if name in ("rerun.controls.RowId", "log_time"):
                continue
            if name == "sim_time":
                vals = [None if v is None else v / 1e9 for v in col.cast("int64").to_pylist()]
            else:
                vals = _column_values(col)
            for r, v in zip(rows, vals, strict=True):
                r[name] = v
        out.setdefault(chunk.entity_path, []).extend(rows)
    for rows in out.values():
        rows.sort(key=lambda r: (not r["static"], r["step"] if r["step"] is not None else -1,
                                 r["sim_time"] if r["sim_time"] is not None else -1.0))
    return out


def _column_values(col) -> list:
    t = col.type
    is_blob = (hasattr(t, "value_type") and hasattr(t.value_type, "value_type")
               and str(t.value_type.value_type) == "uint8")
    if not is_blob:
        return col.to_pylist()
    return [None if not row.is_valid else [np.asarray(b.values.to_numpy(zero_copy_only=False), np.uint8)
                                           for b in row.values] for row in col]
