"""Helpers of the tests that drive the CLIs in child processes (signals, waiting for a file or a port)."""

from __future__ import annotations

import signal
import time


def sigint_default():
    """In the child (``preexec_fn``): Ctrl-C as a terminal delivers it, even when the test runner was
    started with SIGINT ignored (nohup, a background job), which Python would otherwise pass on to the
    child."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def wait_for(pred, timeout_s, what):
    """Poll ``pred`` until it holds; AssertionError naming ``what`` after ``timeout_s`` seconds."""
    t0 = time.monotonic()
    while not pred():
        if time.monotonic() - t0 > timeout_s:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def run_capped(cmd, tmp_path, *, timeout_s: float = 60.0, mem_bytes: int = 3 << 30, fsize_bytes: int | None = None,
               cwd=None, env=None):
    """Run ``cmd`` with its address space capped at ``mem_bytes`` (a regression cannot take the machine
    down), optionally its file sizes at ``fsize_bytes`` (writes beyond fail with EFBIG, as on a full disk:
    SIGXFSZ ignored) and a timeout (killed, AssertionError: a hang). Returns (exit code, stdout, stderr,
    peak resident memory in bytes, from the child's own rusage)."""
    import os
    import resource
    import subprocess

    def limits():
        resource.setrlimit(resource.RLIMIT_AS, (mem_bytes, mem_bytes))
        if fsize_bytes is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize_bytes, fsize_bytes))

    out_p, err_p = tmp_path / "child.stdout", tmp_path / "child.stderr"
    with open(out_p, "wb") as out, open(err_p, "wb") as err:
        proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=out, stderr=err, preexec_fn=limits, cwd=cwd,
                                env=env)
    t0 = time.monotonic()
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        if time.monotonic() - t0 > timeout_s:
            proc.kill()
            os.wait4(proc.pid, 0)
            proc.returncode = -9
            raise AssertionError(f"{cmd} did not finish within {timeout_s} s (a hang)")
        time.sleep(0.05)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return (proc.returncode, out_p.read_text(errors="replace"), err_p.read_text(errors="replace"),
            usage.ru_maxrss * 1024)
