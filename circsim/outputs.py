"""``circsim run``'s outputs, checked before the first tick: none may be an input or another output, the
bag's folder holds no other output, and each one's folder can be written. A check creates nothing (the
missing folders are made by :func:`make_folders` once every check has passed), so a refused command leaves
the disk as it was."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from .commands import UsageError


def _nearest_folder(path: Path) -> Path:
    """The nearest existing ancestor of ``path`` (what a check probes: the folders below it are made later)."""
    d = path.parent
    while not os.path.lexists(d) and d != d.parent:
        d = d.parent
    return d


def _probe(path: Path, message: str) -> None:
    """The folder of ``path`` can be written: its nearest existing ancestor is a folder in which a uniquely
    named probe file can be created (and is deleted at once); else UsageError(``message (the reason)``)."""
    d = _nearest_folder(Path(path))
    if not d.is_dir():
        raise UsageError(f"{message} ({d} is not a folder)")
    try:
        fd, probe = tempfile.mkstemp(prefix=f".{Path(path).name}.", dir=d)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise UsageError(f"{message} ({e.strerror or e})") from None


def writable(path: Path, what: str) -> None:
    """Fail before the run, in one line, if ``path`` cannot be written (nothing is created: a run that stops
    early leaves no empty file, a refused one no empty folder)."""
    if path.is_dir():
        raise UsageError(f"{path}: cannot write the {what} here (a folder has that name)")
    _probe(path, f"{path}: cannot write the {what} here")


def _key(p) -> str:
    return os.path.normcase(os.path.realpath(p))


def check_run_outputs(sc, scenario_arg: str, rrd, json_out, save_maps, bag=None, png=None) -> None:
    """Before the run: no output may be the scenario file, another output (``--rrd X --json X``, a
    ``--json`` inside ``--save-maps`` named like a robot's map), a folder, a link or a special file; and
    no output may be the ``--bag`` folder or lie inside it (a bag is a new folder of its own)."""
    from merger.io.mapio import CENTERS_FILE, check_outputs, map_paths

    from .record.savemaps import file_stem

    outputs = []
    if rrd:
        outputs.append((rrd, "--rrd"))
    if json_out:
        outputs.append((json_out, "--json"))
    if png:
        outputs.append((png, "--png"))
    if save_maps:
        for i, n in enumerate(sc.robots.names):
            outputs += [(p, "--save-maps") for p in map_paths(save_maps / f"{file_stem(n, i)}.yaml")]
        outputs.append((save_maps / CENTERS_FILE, "--save-maps"))
    if bag:
        b = _key(bag)
        for p, what in ([(save_maps, "--save-maps")] if save_maps else []) + outputs:
            k = _key(p)
            if k == b:
                raise UsageError(f"{what} {p}: is also written by --bag ({bag}): expected distinct outputs")
            if k.startswith(b + os.sep):
                raise UsageError(f"{what} {p}: is inside the --bag folder {bag} (a bag is a new folder of its "
                                 "own): expected an output outside it")
    p = Path(scenario_arg)
    check_outputs(outputs, {p: "scenario"} if p.is_file() else {})


def check_bag_output(path: Path) -> None:
    """Before the run, in one line (UsageError): rosbags is installed, ``path`` does not exist (a bag is a
    folder; circsim never deletes one) and its folder is writable."""
    from .record.bag import rosbags_missing

    hint = rosbags_missing()
    if hint:
        raise UsageError(hint)
    path = Path(path)
    if path.exists() or path.is_symlink():
        raise UsageError(f"--bag {path}: already exists (a ROS 2 bag is a folder; circsim does not overwrite "
                         "one): name a new path")
    _probe(path, f"--bag {path}: cannot write the bag here")


def check_maps_folder(path: Path) -> None:
    """``--save-maps DIR``: DIR is a folder or can be made, and can be written."""
    if os.path.lexists(path) and not path.is_dir():
        raise UsageError(f"--save-maps {path}: cannot write there (not a folder)")
    _probe(path / "x", f"--save-maps {path}: cannot write there")


def make_folders(*folders) -> None:
    """Once every check has passed: make the outputs' missing folders (one line naming it if one cannot be)."""
    for d in folders:
        if d is None:
            continue
        try:
            Path(d).mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise UsageError(f"{d}: cannot make the folder ({e.strerror or e})") from None
