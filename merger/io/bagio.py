"""Occupancy grids from ROS 2 bags (``nav_msgs/msg/OccupancyGrid``), read with the pure-Python ``rosbags``
library: no ROS installation needed (``pip install 'circsim[bag]'``).

A map topic (``/r1/map``) is latched and republished as the map grows: the last message of each topic
is the robot's newest map. The message's grid is already in the convention of :mod:`merger.grid` (int8,
−1 unknown, 0..100 occupancy, row-major, row 0 at the origin); a cell is occupied above 65, free below
19.6 (map_server's thresholds), unknown otherwise. A rotated origin is refused, as in :mod:`merger.io.mapread`,
and so are what a map file may not hold either: a cell size outside [``MIN_RESOLUTION_M``, 1000 m], an
origin beyond ``MAX_ORIGIN_M``, and cell values outside −1..100 (a 127 is not "occupied": it is no
OccupancyGrid value at all).

Every problem raises :class:`merger.io.mapread.MapFileError` naming the bag and the topic.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..grid import OccupancyGrid
from .mapread import MAX_ORIGIN_M, MIN_RESOLUTION_M, MapFileError

MSGTYPE = "nav_msgs/msg/OccupancyGrid"
MAX_CELLS = 100_000_000
MAX_RESOLUTION_M = 1e3  # as a map file's `resolution` (merger.io.mapread)


def _rosbags():
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise MapFileError("--bag: reading ROS 2 bags needs the rosbags library; install the bag extra: "
                           "pip install 'circsim[bag]'") from None
    return AnyReader, get_typestore(Stores.ROS2_HUMBLE)


def grid_from_message(msg, where: str) -> OccupancyGrid:
    """A ``nav_msgs/msg/OccupancyGrid`` message (deserialized) as an :class:`OccupancyGrid`."""
    info = msg.info
    w, h, res = int(info.width), int(info.height), float(info.resolution)
    if not (math.isfinite(res) and MIN_RESOLUTION_M <= res <= MAX_RESOLUTION_M):
        raise MapFileError(f"{where}: info.resolution: expected a cell size in [{MIN_RESOLUTION_M:g}, "
                           f"{MAX_RESOLUTION_M:g}] m, got {res!r}")
    if w <= 0 or h <= 0 or w * h > MAX_CELLS:
        raise MapFileError(f"{where}: info.width x info.height: expected a non-empty grid of at most "
                           f"{MAX_CELLS} cells, got {w} x {h}")
    data = np.asarray(msg.data, dtype=np.int8)
    if data.size != w * h:
        raise MapFileError(f"{where}: data: expected width x height = {w * h} cells, got {data.size}")
    bad = np.flatnonzero((data < -1) | (data > 100))
    if bad.size:
        raise MapFileError(f"{where}: data: expected cell values in -1..100 (-1 unknown, 0..100 occupancy), got "
                           f"{int(data[bad[0]])} (cell {int(bad[0])}; {bad.size} such cells)")
    p, q = info.origin.position, info.origin.orientation
    x, y = float(p.x), float(p.y)
    if not (math.isfinite(x) and math.isfinite(y) and abs(x) <= MAX_ORIGIN_M and abs(y) <= MAX_ORIGIN_M):
        raise MapFileError(f"{where}: info.origin.position: expected finite numbers within {MAX_ORIGIN_M:g} m, "
                           f"got ({x}, {y})")
    yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
    if abs(yaw) > 1e-6:
        raise MapFileError(f"{where}: info.origin.orientation: a rotated origin (yaw {math.degrees(yaw):.3f}°) "
                           "is not supported")
    return OccupancyGrid.from_ros(data.reshape(h, w), res, (x, y))


def check_outputs_outside(bag, outputs: dict) -> None:
    """Before any work: no output (``{path: option}``) may be the input bag or lie inside it (``merger merge
    --bag B -o B/metadata`` overwrote the bag's metadata.yaml, issue 46). MapFileError naming both."""
    import os

    b = os.path.normcase(os.path.realpath(bag))
    for p, what in outputs.items():
        k = os.path.normcase(os.path.realpath(p))
        if k == b or k.startswith(b.rstrip(os.sep) + os.sep):
            raise MapFileError(f"{what} {p}: is inside the input bag {bag}: expected an output outside it "
                               "(a bag is read, never written)")


def check_bag_files(path: Path) -> None:
    """A bag is a regular file or a folder of regular files: a FIFO (or a device) would block the reader
    or feed it forever (issue 26). MapFileError naming the file otherwise."""
    import stat

    for p in [path, *(sorted(path.iterdir()) if path.is_dir() else [])]:
        mode = p.stat().st_mode
        if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
            raise MapFileError(f"{p}: expected a ROS bag file (or a ROS 2 bag folder of files), got "
                               f"{'a FIFO' if stat.S_ISFIFO(mode) else 'a device or special file'}")


def _open(path: Path):
    """The bag at ``path`` opened with rosbags (MapFileError naming the file when it is not one)."""
    AnyReader, typestore = _rosbags()
    if not path.exists():
        raise MapFileError(f"{path}: no such bag")
    check_bag_files(path)
    try:
        reader = AnyReader([path], default_typestore=typestore)
        reader.open()
    except Exception as e:  # rosbags raises its own errors for anything that is not a bag
        raise MapFileError(f"{path}: not a readable ROS bag ({type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''})") \
            from None
    return reader


def _map_topics(reader, path: Path, topics: list[str]) -> dict:
    """The bag's connections by topic, after checking that each of ``topics`` is an OccupancyGrid topic."""
    by_topic = {c.topic: c for c in reader.connections}
    maps_here = sorted(t for t, c in by_topic.items() if c.msgtype == MSGTYPE)
    for t in topics:
        if t not in by_topic:
            raise MapFileError(f"{path}: topic {t}: not in the bag (its {MSGTYPE} topics: "
                               f"{', '.join(maps_here) or 'none'})")
        if by_topic[t].msgtype != MSGTYPE:
            raise MapFileError(f"{path}: topic {t}: expected {MSGTYPE}, got {by_topic[t].msgtype}")
    return by_topic


def read_bag_maps(path, topics: list[str]) -> dict[str, OccupancyGrid]:
    """The last ``nav_msgs/msg/OccupancyGrid`` of each of ``topics`` in the bag at ``path`` (a ROS 2 bag
    folder, or a ROS 1 ``.bag``), in the order of ``topics``."""
    path = Path(path)
    reader = _open(path)
    try:
        by_topic = _map_topics(reader, path, topics)
        last: dict[str, tuple[int, bytes, object]] = {}
        for conn, stamp, raw in reader.messages(connections=[by_topic[t] for t in topics]):
            if conn.topic not in last or stamp >= last[conn.topic][0]:
                last[conn.topic] = (stamp, raw, conn)
        out = {}
        for t in topics:
            if t not in last:
                raise MapFileError(f"{path}: topic {t}: no message in the bag")
            _, raw, conn = last[t]
            try:
                msg = reader.deserialize(raw, conn.msgtype)
            except Exception as e:
                raise MapFileError(f"{path}: topic {t}: cannot decode the message ({type(e).__name__})") from None
            out[t] = grid_from_message(msg, f"{path}: topic {t}")
        return out
    finally:
        reader.close()


def topic_names(topics: list[str]) -> list[str]:
    """Short distinct map names for topics: ``/r1/map`` → ``r1`` when every topic ends in ``/map``, else
    the topic without its leading slash."""
    names = [t.strip("/") for t in topics]
    short = [n[: -len("/map")] for n in names if n.endswith("/map") and n != "/map"]
    if len(short) == len(names) and all(short) and len(set(short)) == len(short):
        return short
    return names


def read_bag_map_series(path, topics: list[str], *, stamp: str = "header") -> dict[str, list[tuple[float, OccupancyGrid]]]:
    """Every ``nav_msgs/msg/OccupancyGrid`` of each of ``topics`` in the bag at ``path``, in time order, as
    ``(seconds, grid)``: the message's header stamp (``stamp="header"``) or the bag's receive time
    (``stamp="bag"``). Errors as :func:`read_bag_maps`."""
    path = Path(path)
    reader = _open(path)
    try:
        by_topic = _map_topics(reader, path, topics)
        out: dict[str, list] = {t: [] for t in topics}
        for conn, ns, raw in reader.messages(connections=[by_topic[t] for t in topics]):
            where = f"{path}: topic {conn.topic}"
            try:
                msg = reader.deserialize(raw, conn.msgtype)
            except Exception as e:
                raise MapFileError(f"{where}: cannot decode a message ({type(e).__name__})") from None
            s = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec if stamp == "header" else ns * 1e-9
            out[conn.topic].append((s, grid_from_message(msg, where)))
        for v in out.values():
            v.sort(key=lambda e: e[0])
        return out
    finally:
        reader.close()
