"""merger/jit.py: a corrupt, unwritable or missing numba cache costs a compile and one warning line, never a
run (issue 37, item 1). The cache cases run a two-kernel module in a child process with its own
``NUMBA_CACHE_DIR``, so the project's cache is never touched."""

from __future__ import annotations

import ast
import importlib
import logging
import os
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest
from numba.core.registry import CPUDispatcher

import circsim
import merger
from merger.jit import GuardedCache, njit

ROOT = Path(__file__).resolve().parents[2]
KERNELS = """
from merger.jit import njit

@njit(cache=True, nogil=True)
def add(a, b):
    return a + 2 * b

@njit(cache=True, nogil=True)
def twice(a):
    return add(a, a)

print(twice(3), twice(2.5))
"""


def run_module(tmp_path: Path, env_extra=None, preexec_fn=None):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": str(ROOT)}
    env.pop("NUMBA_CACHE_LOCATOR_CLASSES", None)
    env.update(env_extra or {})
    p = subprocess.run([sys.executable, str(tmp_path / "kmod.py")], capture_output=True, text=True, env=env,
                       timeout=120, preexec_fn=preexec_fn)
    return p.returncode, p.stdout, [ln for ln in p.stderr.splitlines() if ln.strip()]


def cache_files(tmp_path: Path, suffix: str) -> list[Path]:
    return sorted((tmp_path / "cache").rglob(f"kmod.*{suffix}"))


def prepared(tmp_path: Path) -> None:
    (tmp_path / "kmod.py").write_text(KERNELS)
    assert run_module(tmp_path) == (0, "9 7.5\n", [])
    assert len(cache_files(tmp_path, ".nbc")) == 4 and len(cache_files(tmp_path, ".nbi")) == 2


@pytest.mark.slow
def test_truncated_data_files_are_discarded_with_one_warning_and_the_cache_rewritten(tmp_path):
    """An .nbc cut to half (a full disk, a killed first compile): numba's own cache raised UnpicklingError
    on every later run."""
    prepared(tmp_path)
    for f in cache_files(tmp_path, ".nbc"):
        f.write_bytes(f.read_bytes()[: f.stat().st_size // 2])
    code, out, err = run_module(tmp_path)
    assert (code, out) == (0, "9 7.5\n"), err
    assert len(err) == 1 and err[0].startswith("warning: numba's compile cache in ") and "truncated" in err[0], err
    assert run_module(tmp_path) == (0, "9 7.5\n", [])  # rewritten: the next run loads it silently


@pytest.mark.slow
def test_a_garbled_index_is_discarded_with_one_warning(tmp_path):
    prepared(tmp_path)
    for f in cache_files(tmp_path, ".nbi"):
        f.write_bytes(b"\x80\x04garbage" * 7)
    code, out, err = run_module(tmp_path)
    assert (code, out) == (0, "9 7.5\n") and len(err) == 1 and "could not be read" in err[0], err
    assert run_module(tmp_path) == (0, "9 7.5\n", [])


def test_a_cache_that_cannot_be_written_is_one_warning(tmp_path):
    """Every cache write fails (files capped at 1 kB: EFBIG, as on a full disk): the kernels still run."""
    import resource
    import signal

    def small_files():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (1024, 1024))

    (tmp_path / "kmod.py").write_text(KERNELS)
    code, out, err = run_module(tmp_path, preexec_fn=small_files)
    assert (code, out) == (0, "9 7.5\n") and len(err) == 1 and "could not be written" in err[0], err


def test_no_place_to_cache_compiles_in_memory_with_one_warning():
    """No locator (every numba locator refuses: here none is allowed): ``import merger`` raised
    ``cannot cache function 'state_at': no locator available``."""
    env = {**os.environ, "NUMBA_CACHE_LOCATOR_CLASSES": "IPythonCacheLocator", "PYTHONPATH": str(ROOT)}
    p = subprocess.run([sys.executable, "-c", "import merger, circsim.slam.scanmatch, merger.cli; print('ok')"],
                       capture_output=True, text=True, env=env, timeout=120)
    err = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert (p.returncode, p.stdout) == (0, "ok\n"), p.stderr
    assert len(err) == 1 and "no writable folder" in err[0] and "NUMBA_CACHE_DIR" in err[0], err


def test_a_function_without_a_source_file_runs_compiled_in_memory(caplog):
    scope: dict = {}
    exec(compile("def f(x):\n    return x * 3\n", "<no file>", "exec"), scope)
    with caplog.at_level(logging.WARNING, logger="merger.jit"):
        import merger.jit as jit

        jit._told.discard("nowhere")
        f = njit(cache=True, nogil=True)(scope["f"])
    assert f(4) == 12
    assert [r.getMessage() for r in caplog.records if "no writable folder" in r.getMessage()]


def _modules(pkg):
    yield pkg.__name__
    for info in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
        yield info.name


def test_every_kernel_of_merger_and_circsim_goes_through_the_guarded_cache():
    """Statically (no module imports numba's njit but merger/jit.py) and at run time (every compiled
    function of every module caches through GuardedCache, nogil, no fastmath)."""
    for py in sorted([*(ROOT / "merger").rglob("*.py"), *(ROOT / "circsim").rglob("*.py")]):
        if py == ROOT / "merger" / "jit.py":
            continue
        for node in ast.walk(ast.parse(py.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "numba":
                names = {a.name for a in node.names}
                assert not names & {"njit", "jit"}, f"{py}: import njit from merger.jit, not numba"
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "numba":
                assert node.attr not in {"njit", "jit"}, f"{py}: use merger.jit.njit"
    found = 0
    for pkg in (merger, circsim):
        for name in _modules(pkg):
            if name.endswith("__main__"):
                continue
            mod = importlib.import_module(name)
            for attr, value in vars(mod).items():
                if isinstance(value, CPUDispatcher) and value.py_func.__module__ == name:
                    found += 1
                    assert isinstance(value._cache, GuardedCache), f"{name}.{attr}"
                    assert value.targetoptions.get("nogil") and not value.targetoptions.get("fastmath"), attr
    assert found >= 30  # merger's search and evidence kernels, circsim's scan matcher


DEPENDENT = """
from merger.jit import njit
from kdep import add

@njit(cache=True, nogil=True)
def twice(a):
    return add(a, a)

print(twice(3))
"""


def test_a_kernel_is_compiled_again_when_a_kernel_it_calls_changed_in_another_file(tmp_path):
    """numba's cache checks only the kernel's own file, while a cached kernel holds the code of the
    kernels it calls: after an edit of ``add`` in another file, ``twice`` loaded from the cache ran the
    old ``add`` (found when a fixed bound in merger/search/bounds.py still answered wrongly through the
    branch and bound of bnb.py)."""
    (tmp_path / "kdep.py").write_text(KERNELS.split("@njit(cache=True, nogil=True)\ndef twice")[0])
    (tmp_path / "kmod.py").write_text(DEPENDENT)
    env = {"PYTHONPATH": f"{ROOT}{os.pathsep}{tmp_path}"}
    assert run_module(tmp_path, env) == (0, "9\n", [])  # 3 + 2·3
    assert run_module(tmp_path, env) == (0, "9\n", [])  # from the cache
    src = (tmp_path / "kdep.py").read_text().replace("a + 2 * b", "a + 3 * b")
    (tmp_path / "kdep.py").write_text(src)
    assert run_module(tmp_path, env) == (0, "12\n", [])  # 3 + 3·3: compiled again, not the cached 9


@pytest.mark.parametrize("kind", ["file", "under_a_file"])
def test_an_unusable_numba_cache_dir_is_said_once_with_where_the_kernels_go(tmp_path, kind):
    """NUMBA_CACHE_DIR that is a file (or on a read-only mount) gave no warning: numba silently cached
    beside the sources instead (issue 46, item 10)."""
    (tmp_path / "kmod.py").write_text(KERNELS)
    (tmp_path / "afile").write_text("")
    d = tmp_path / "afile" if kind == "file" else tmp_path / "afile" / "sub"
    code, out, err = run_module(tmp_path, {"NUMBA_CACHE_DIR": str(d)})
    assert (code, out) == (0, "9 7.5\n"), err
    assert len(err) == 1, err
    why = "it is not a folder" if kind == "file" else "it cannot be made"
    assert err[0].startswith(f"warning: NUMBA_CACHE_DIR={d}: cannot be used to cache compiled kernels ({why}); "
                             "they are cached beside their sources instead (__pycache__: "), err[0]
