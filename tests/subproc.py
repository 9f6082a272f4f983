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
