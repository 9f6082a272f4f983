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


# Runs the command in a grandchild and reports its exit code and peak memory. Linux carries a process's
# peak resident memory across exec, so a child forked from a large test process (a pytest worker holds
# hundreds of MB after the tests before) would report the worker's size; the grandchild is forked from
# this small launcher instead, so its ru_maxrss is the command's own.
_LAUNCH = """
import os, sys
pid = os.fork()
if pid == 0:
    try:
        os.execvp(sys.argv[2], sys.argv[2:])
    finally:
        os._exit(127)
_, status, usage = os.wait4(pid, 0)
with open(sys.argv[1], "w") as f:
    f.write(f"{os.waitstatus_to_exitcode(status)} {usage.ru_maxrss}")
"""


def run_capped(cmd, tmp_path, *, timeout_s: float = 60.0, mem_bytes: int = 3 << 30, fsize_bytes: int | None = None,
               cwd=None, env=None):
    """Run ``cmd`` with its address space capped at ``mem_bytes`` (a regression cannot take the machine
    down), optionally its file sizes at ``fsize_bytes`` (writes beyond fail with EFBIG, as on a full disk:
    SIGXFSZ ignored) and a timeout (killed, AssertionError: a hang). Returns (exit code, stdout, stderr,
    peak resident memory in bytes, from the command's own rusage: it runs under a small launcher,
    :data:`_LAUNCH`, so the test process's own size does not count)."""
    import os
    import resource
    import subprocess
    import sys

    def limits():
        resource.setrlimit(resource.RLIMIT_AS, (mem_bytes, mem_bytes))
        if fsize_bytes is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize_bytes, fsize_bytes))

    out_p, err_p, rep_p = tmp_path / "child.stdout", tmp_path / "child.stderr", tmp_path / "child.rusage"
    rep_p.unlink(missing_ok=True)
    launcher = [sys.executable, "-I", "-c", _LAUNCH, str(rep_p), *(str(c) for c in cmd)]
    with open(out_p, "wb") as out, open(err_p, "wb") as err:
        proc = subprocess.Popen(launcher, stdin=subprocess.DEVNULL, stdout=out, stderr=err, preexec_fn=limits,
                                cwd=cwd, env=env, start_new_session=True)
    try:
        proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)  # the launcher and the command
        proc.wait()
        raise AssertionError(f"{cmd} did not finish within {timeout_s} s (a hang)") from None
    code, maxrss_kb = (int(x) for x in rep_p.read_text().split())
    return (code, out_p.read_text(errors="replace"), err_p.read_text(errors="replace"), maxrss_kb * 1024)
