"""``circsim run --bag OUT``: the run as a ROS 2 bag (MCAP), for any map merger to be judged on.

Written with the pure-Python ``rosbags`` library (``pip install -e ".[ros]"``; no ROS install needed).
The bag is a folder ``OUT/`` (``metadata.yaml`` + ``OUT.mcap``), written inside a locked temporary folder
``.OUT.XXXX.part.bag/`` beside it and renamed when the run ends (Ctrl-C included): a reader never sees half
a bag, and the next run of the same ``OUT`` deletes the parts a killed run left (:mod:`circsim.record.parts`).
A bag that cannot be written (a full disk) is dropped at the first failed write with one line in
:attr:`BagRecorder.write_error`; the run goes on and its other outputs are kept. Topics, per robot ``r``
(stamps are simulated seconds from 0; the bag's clock is the same)::

    /r/map        nav_msgs/msg/OccupancyGrid   frame r/map, at every publication (transient-local QoS)
    /r/scan       sensor_msgs/msg/LaserScan    frame r/laser, every tick (REP-117: inf, -inf, NaN)
    /r/odom       nav_msgs/msg/Odometry        r/odom -> r/base_link: the SLAM's pose estimate, every tick
    /tf           tf2_msgs/msg/TFMessage       per tick and robot: r/map -> r/odom (identity: the bench's SLAM
                                               fuses odometry and scan matching into one estimate) and
                                               r/odom -> r/base_link (that estimate, in the map frame M_r)
    /tf_static    tf2_msgs/msg/TFMessage       r/base_link -> r/laser (identity: the laser is the robot frame)

The ground truth is not in the topics (a merger must not see it): ``OUT/circsim_truth.yaml`` holds each
robot's given and true center (in its map frame), start pose (world), and per pair (i, j) the true
placement of map j onto map i — as the rigid pose of frame j/map in frame i/map (``yaw_deg, x_m, y_m``)
and about the given centers as the run's metrics judge it (``theta_deg``, ``t_m``: x_i = c_i + t +
R(θ)(x_j − c_j)) — and the correctness tolerances. ``OUT/circsim_merges.csv`` holds the bench's own
accepted merges in the format ``circsim score --transforms`` reads (:mod:`circsim.score`): scoring it
reproduces the run's first merges and false merges. ``ros2 bag`` ignores both files.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
import shutil
from pathlib import Path

import numpy as np

from ..events import Observer

TRUTH_FILE = "circsim_truth.yaml"
MERGES_FILE = "circsim_merges.csv"
CSV_HEADER = "estimate,t_s,robot,map,yaw_deg,x_m,y_m"
INSTALL_HINT = "--bag needs the rosbags library: pip install -e \".[ros]\" (or pip install 'rosbags>=0.11,<0.12')"


def rosbags_missing() -> str | None:
    """The one-line install hint when rosbags cannot be imported, else None."""
    try:
        import rosbags.rosbag2  # noqa: F401
        import rosbags.typesys  # noqa: F401
    except ImportError:
        return INSTALL_HINT
    return None


def rigid_from_center(theta_deg: float, t, c_i, c_j) -> tuple[float, float, float]:
    """The pose (yaw_deg, x, y) of frame j/map in frame i/map for the alignment x_i = c_i + t + R(θ)(x_j − c_j):
    x_i = R(θ)·x_j + p with p = c_i + t − R(θ)·c_j."""
    a = math.radians(theta_deg)
    c, s = math.cos(a), math.sin(a)
    return (theta_deg, c_i[0] + t[0] - (c * c_j[0] - s * c_j[1]), c_i[1] + t[1] - (s * c_j[0] + c * c_j[1]))


def ros_name(robot: str) -> str:
    """A robot's name as a ROS name token (topics ``/<name>/map``, frames ``<name>/map``): letters, digits and
    '_' (anything else becomes '_'), not starting with a digit."""
    s = re.sub(r"[^A-Za-z0-9_]", "_", robot)
    return s if s and not s[0].isdigit() else f"r_{s}"


def _stamp_ns(t: float) -> int:
    return int(round(t * 1e9))


class BagRecorder(Observer):
    """Observer writing the run as a ROS 2 bag at ``path`` (a folder that must not exist yet)."""

    def __init__(self, path: Path) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.path = Path(path)
        self.ts = get_typestore(Stores.ROS2_HUMBLE)
        self.T = self.ts.types
        self.writer = None
        self.tmp: Path | None = None
        self.conns: dict = {}
        self.merges: list[tuple] = []
        self._estimate = 0
        self._last_est: dict[str, tuple[float, tuple]] = {}
        self.sim = None
        self.counts: dict[str, int] = {}
        self.write_error: str | None = None  # why the bag was dropped (one line naming it), if so
        self._lock: int | None = None  # the part folder's lock (circsim.record.parts)

    def _guard(self, hook, *args) -> None:
        """Run ``hook`` unless the bag was dropped; an OSError (a full disk, a quota) drops the bag: the
        writer is aborted, its part deleted and :attr:`write_error` names the bag; the run goes on."""
        if self.write_error is not None:
            return
        try:
            hook(*args)
        except OSError as e:
            self.write_error = (f"--bag {self.path}: cannot write the bag ({e.strerror or e}); nothing of it "
                                "was kept")
            self.abort()

    # --- message builders -------------------------------------------------------------------
    def _header(self, t: float, frame: str):
        ns = _stamp_ns(t)
        return self.T["std_msgs/msg/Header"](stamp=self.T["builtin_interfaces/msg/Time"](
            sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id=frame)

    def _quat(self, yaw: float):
        return self.T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))

    def _tf(self, t: float, parent: str, child: str, x: float, y: float, yaw: float):
        T = self.T
        tr = T["geometry_msgs/msg/Transform"](translation=T["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=0.0),
                                              rotation=self._quat(float(yaw)))
        return T["geometry_msgs/msg/TransformStamped"](header=self._header(t, parent), child_frame_id=child,
                                                       transform=tr)

    def _write(self, topic: str, t: float, msg) -> None:
        conn = self.conns[topic]
        self.writer.write(conn, _stamp_ns(t), self.ts.serialize_cdr(msg, conn.msgtype))
        self.counts[topic] = self.counts.get(topic, 0) + 1

    # --- observer hooks ---------------------------------------------------------------------
    def on_start(self, sim) -> None:
        self._guard(self._start, sim)

    def on_tick(self, t, step, ticks) -> None:
        self._guard(self._tick, t, step, ticks)

    def on_map_published(self, t, robot, grid, center_given, center_true) -> None:
        self._guard(self._map, t, robot, grid)

    def on_merge_cycle(self, cycle) -> None:
        self._guard(self._merges, cycle)

    def on_end(self, result) -> None:
        self._guard(self._end)

    def _start(self, sim) -> None:
        from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
        from rosbags.rosbag2 import StoragePlugin, Writer

        from .parts import claim_bag_part

        self.sim = sim
        self.path.parent.mkdir(parents=True, exist_ok=True)
        part, self._lock = claim_bag_part(self.path)
        self.tmp = part / self.path.name
        self.writer = Writer(self.tmp, version=9, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        zero = QosTime(sec=0, nsec=0)
        latched = [Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL, zero, zero,
                       QosLiveliness.AUTOMATIC, zero, False)]
        add = self.writer.add_connection
        self.ns = {}
        for i, r in enumerate(sim.robot_names):  # distinct ROS names, in the robots' order
            n = ros_name(r)
            self.ns[r] = n if n not in self.ns.values() else f"{n}_{i}"
        for n in self.ns.values():
            self.conns[f"/{n}/map"] = add(f"/{n}/map", "nav_msgs/msg/OccupancyGrid", typestore=self.ts,
                                          offered_qos_profiles=latched)
            self.conns[f"/{n}/scan"] = add(f"/{n}/scan", "sensor_msgs/msg/LaserScan", typestore=self.ts)
            self.conns[f"/{n}/odom"] = add(f"/{n}/odom", "nav_msgs/msg/Odometry", typestore=self.ts)
        self.conns["/tf"] = add("/tf", "tf2_msgs/msg/TFMessage", typestore=self.ts)
        self.conns["/tf_static"] = add("/tf_static", "tf2_msgs/msg/TFMessage", typestore=self.ts,
                                       offered_qos_profiles=latched)
        self._write("/tf_static", 0.0, self.T["tf2_msgs/msg/TFMessage"](
            transforms=[self._tf(0.0, f"{n}/base_link", f"{n}/laser", 0.0, 0.0, 0.0) for n in self.ns.values()]))

    def _tick(self, t, step, ticks) -> None:
        T = self.T
        tfs = []
        for k in ticks:
            n, s = self.ns[k.name], k.scan
            x, y, yaw = (float(v) for v in k.est_pose)
            tfs.append(self._tf(t, f"{n}/map", f"{n}/odom", 0.0, 0.0, 0.0))
            tfs.append(self._tf(t, f"{n}/odom", f"{n}/base_link", x, y, yaw))
            self._write(f"/{n}/scan", t, T["sensor_msgs/msg/LaserScan"](
                header=self._header(t, f"{n}/laser"), angle_min=float(s.angle_min), angle_max=float(s.angle_max),
                angle_increment=float(s.angle_increment), time_increment=0.0,
                scan_time=float(self.sim.scenario.dt_s), range_min=float(s.range_min), range_max=float(s.range_max),
                ranges=np.asarray(s.ranges, dtype=np.float32), intensities=np.zeros(0, np.float32)))
            self._write(f"/{n}/odom", t, self._odometry(t, n, x, y, yaw))
        self._write("/tf", t, T["tf2_msgs/msg/TFMessage"](transforms=tfs))

    def _odometry(self, t: float, n: str, x: float, y: float, yaw: float):
        """The SLAM estimate as nav_msgs/Odometry; the twist (in the body frame) from the last estimate."""
        T = self.T
        vx = vy = wz = 0.0
        last = self._last_est.get(n)
        if last is not None and t > last[0]:
            dt = t - last[0]
            px, py, pyaw = last[1]
            c, s = math.cos(yaw), math.sin(yaw)
            dx, dy = x - px, y - py
            vx, vy = (c * dx + s * dy) / dt, (-s * dx + c * dy) / dt
            wz = math.remainder(yaw - pyaw, 2 * math.pi) / dt
        self._last_est[n] = (t, (x, y, yaw))
        cov = np.zeros(36, np.float64)
        pose = T["geometry_msgs/msg/PoseWithCovariance"](pose=T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0), orientation=self._quat(yaw)), covariance=cov)
        V3 = T["geometry_msgs/msg/Vector3"]
        twist = T["geometry_msgs/msg/TwistWithCovariance"](twist=T["geometry_msgs/msg/Twist"](
            linear=V3(x=vx, y=vy, z=0.0), angular=V3(x=0.0, y=0.0, z=wz)), covariance=cov)
        return T["nav_msgs/msg/Odometry"](header=self._header(t, f"{n}/odom"), child_frame_id=f"{n}/base_link",
                                          pose=pose, twist=twist)

    def _map(self, t, robot, grid) -> None:
        T = self.T
        Time = T["builtin_interfaces/msg/Time"]
        ns = _stamp_ns(t)
        origin = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=float(grid.origin[0]), y=float(grid.origin[1]), z=0.0),
            orientation=self._quat(0.0))
        info = T["nav_msgs/msg/MapMetaData"](map_load_time=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000),
                                             resolution=float(grid.resolution), width=int(grid.width),
                                             height=int(grid.height), origin=origin)
        n = self.ns[robot]
        self._write(f"/{n}/map", t, T["nav_msgs/msg/OccupancyGrid"](
            header=self._header(t, f"{n}/map"), info=info,
            data=np.ascontiguousarray(grid.to_ros().ravel(), dtype=np.int8)))

    def _merges(self, cycle) -> None:
        """Every accepted merge (or adopted hypothesis) as CSV rows: the pose of each teammate's map frame in
        the merging robot's, written with ``repr`` (exact floats) so that scoring reproduces the run."""
        if not cycle.result.accepted:
            return
        c = cycle.result.chosen
        self._estimate += 1
        i = cycle.robot
        for k in c.theta_deg:
            if k == i:
                continue
            yaw, x, y = rigid_from_center(float(c.theta_deg[k]), c.translation(k), self.sim.centers_given[i],
                                          self.sim.centers_given[k])
            self.merges.append((self._estimate, repr(cycle.t), i, k, repr(yaw), repr(x), repr(y)))

    def truth(self) -> dict:
        """The ground truth of the run (the content of ``circsim_truth.yaml``)."""
        sim = self.sim
        sc = sim.scenario
        robots, pairs = {}, {}
        for n in sim.robot_names:
            r, p = sim.robots[n], sim.start_poses[n]
            robots[n] = {"map_topic": f"/{self.ns[n]}/map", "map_frame": f"{self.ns[n]}/map",
                         "center_given": [float(v) for v in r.center_given],
                         "center_true": [float(v) for v in r.center_true],
                         "start_pose_world": [float(p.x), float(p.y), math.degrees(p.yaw) % 360.0]}
        for i in sim.robot_names:
            pi = sim.start_poses[i]
            ci, si = math.cos(pi.yaw), math.sin(pi.yaw)
            pairs[i] = {}
            for j in sim.robot_names:
                if j == i:
                    continue
                pj = sim.start_poses[j]
                dx, dy = pj.x - pi.x, pj.y - pi.y
                pairs[i][j] = {"yaw_deg": float(sim.truth_deg[i][j]), "x_m": ci * dx + si * dy,
                               "y_m": -si * dx + ci * dy, "theta_deg": float(sim.truth_deg[i][j]),
                               "t_m": [float(v) for v in sim.truth_translation_m[i][j]]}
        return {"format": "circsim-truth 1", "scenario": sc.name, "seed": int(sim.seed),
                "sim_s": float(sim.result.sim_s), "robots": robots, "truth": pairs,
                "tolerance": {"deg": float(sc.merger.correct_tol_deg), "m": float(sc.merger.correct_tol_m)},
                "note": "truth[i][j]: map j onto map i. yaw_deg, x_m, y_m: the pose of frame j/map in frame i/map "
                        "(x_i = R(yaw) x_j + (x, y)); theta_deg, t_m: about the given centers, x_i = c_i + t + "
                        "R(theta)(x_j - c_j), as circsim's metrics judge a merge"}

    def abort(self) -> None:
        """The run failed before its end, or the bag could not be written: no bag, and no temporary folder
        left behind."""
        from .parts import release

        if self.writer is not None:
            writer, self.writer = self.writer, None
            try:
                writer.abort()
            except OSError:
                pass
        if self.tmp is not None:
            shutil.rmtree(self.tmp.parent, ignore_errors=True)
            self.tmp = None
        release(self._lock)
        self._lock = None

    def _end(self) -> None:
        import yaml

        from .parts import release

        self.writer.close()
        self.writer = None
        (self.tmp / TRUTH_FILE).write_text(yaml.safe_dump(self.truth(), sort_keys=False, width=110))
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(CSV_HEADER.split(","))
        w.writerows(self.merges)
        (self.tmp / MERGES_FILE).write_text(buf.getvalue())
        if self.path.exists() or self.path.is_symlink():  # another process wrote it meanwhile: keep both
            kept = self.tmp.parent.with_name(self.tmp.parent.name.removesuffix(".part.bag") + ".kept")
            os.replace(self.tmp.parent, kept)
            release(self._lock)
            self.tmp, self._lock = None, None
            self.write_error = (f"--bag {self.path}: appeared during the run (another process wrote it); this "
                                f"run's bag is kept in {kept / self.path.name}")
            return
        os.replace(self.tmp, self.path)
        shutil.rmtree(self.tmp.parent, ignore_errors=True)
        self.tmp = None
        release(self._lock)
        self._lock = None

