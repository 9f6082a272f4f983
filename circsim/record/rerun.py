"""Rerun recording of a run: :class:`RerunRecorder`, and the entity tree it writes.

* :class:`RerunRecorder` is a run :class:`~circsim.events.Observer`: it streams the run to a live viewer
  (``spawn=True``), to an ``.rrd`` file (``path``), or both.
* :mod:`circsim.record.viewer` opens a recorded run (``circsim view RUN.rrd [--web]``) and reads it back;
  :mod:`circsim.record.entities` turns our values into rerun's archetypes. Only ``circsim/record/`` imports
  rerun (tests/test_layout.py checks it).

Why this module is longer than ~400 lines: the recorder is one Observer with one method per event and
per plot (every hook of :class:`~circsim.events.Observer`, the file sink's bounded open and close), and
this docstring is the recording's contract — the entity tree below, which the tests read back.

Entity tree (W = world frame; M_i = robot i's map frame = its start pose in W)::

    /world                                  view coordinates: right-handed, z up (static)
      walls, pillars, objects               LineStrips3D in W (static)
      center                                Points3D, the true common center (static)
      robots/<robot>/circle                 LineStrips3D, the circle it drives (static)
      robots/<robot>/pose                   Transform3D: true pose in W, every tick (+ static arrow and body)
      robots/<robot>/scan                   Points3D: laser returns in W, at ``scan_log_hz``
      robots/<robot>/rays                   LineStrips3D: every 12th beam, at every ``rays_every``-th scan
      robots/<robot>/map                    Transform3D: M_i in W (static); everything below is in M_i
      robots/<robot>/map/local              GridMap: its SLAM map at every publication (cropped*)
      robots/<robot>/map/slam_pose          Transform3D: SLAM pose estimate, every tick (+ static arrow)
      robots/<robot>/map/center_given       Points3D: the center it was given, labelled with its error
      robots/<robot>/map/merged             GridMap: its merged map when it accepts a merge (cropped*)
      robots/<robot>/centers/given          Points3D in W (static): the center it was given, c_i drawn via
                                            its start pose; the true center is /world/center
      robots/<robot>/centers/placed         Points3D in W, at every accepted merge: per teammate j, where the
                                            accepted alignment puts j's given center (c_i + t_ij in M_i)
      robots/<robot>/centers/placed_error   LineStrips3D in W, same times: from each placed point to where
                                            j's given center truly is (robots/<j>/centers/given); its
                                            length is the translation error |t_ij − t*_ij|
    /merge/<robot>/overlay                  Image: the thesis colour overlay of the aligned maps (cropped*)
    /plots/<robot>/omega                    Scalars: score (ω̃ by default) of every alignment step of every order
                                            (strategy tree: of each tree edge's pair search)
    /plots/<robot>/nu                       Scalars: ν of the cycle's top hypothesis per pair, and ν_min
    /plots/<robot>/support                  Scalars: support (agr̃ + dis) per pair, and min_support
    /plots/<robot>/angle_error_deg          Scalars: |θ − θ*| per teammate, at every accepted merge, and
                                            against the estimated-frame truth ("vs SLAM frames")
    /plots/<robot>/translation_error_m      Scalars: |t − t*| (metres) per teammate, at every accepted merge,
                                            and against the estimated-frame truth
    /plots/<robot>/slam_pose_error          Scalars: its SLAM pose estimate's error, every tick: position (cm)
                                            and yaw (°) (sent in columns with the poses)
    /plots/<robot>/cycle_ms                 Scalars: merge cycle cost (wall time + shared results taken, merger.team.memo)
    /plots/<robot>/teammates_placed         Scalars: teammates its held alignment places correctly, and the
                                            maps of the cycle (a partial team merges fewer than all)
    /events/<robot>, /events/sim            TextLog: publications, receptions, merges, run events
    /run/scenario, /run/metrics             TextDocument (static): the scenario and the final metrics JSON

(*) cropped to the known cells plus 1 m (:func:`known_window`); a GridMap's translation is the crop's corner.

Centers: an alignment of map j onto map i is x_i = c_i + t + R(θ)(x_j − c_j), so j's given center c_j lands
at c_i + t in M_i. We draw, per robot i and teammate j, that point (in W, via i's start pose) beside the
true position of j's given center (j's own ``centers/given``): the segment between them is exactly the
translation error, whatever the rotation (a rigid map preserves distances). We do not draw an "implied
common center": with both centers wrong, an alignment fixes only their relative placement.

A plot is one entity with one series per value (names and colours in a static ``SeriesLines``), so a
merge cycle costs one ``rr.log`` per plot.

Timelines: ``sim_time`` (simulated seconds, a duration) and ``step`` (tick index); rerun adds ``log_time``.

y up: rerun's 2D views draw y downward, so the world and every map are shown in *3D* views seen from
above (eye on +z, ``eye_up`` +y): x right, y up, yaw counter-clockwise, as in rviz. A GridMap's first data
row is drawn at its max-y edge, so ROS-ordered grids (row 0 = lowest y) are logged ``np.flipud``-ed; the
overlay is an image in a 2D view (row 0 at the top) and is flipped the same way.

Cost: poses every tick (sent in columns once per simulated second), scans at ``scan_log_hz``, local maps at the publish rate, merged maps and overlays
at most once per ``merged_log_period_s`` of simulated time (default: the SLAM publish period; meanwhile
the newest accepted merge is kept and logged, at its own time, when the period is over; the first,
first-correct and false merges are logged at once).
A run interrupted with Ctrl-C ends with ``on_end``, which closes the file with its footer: the ``.rrd`` is
complete up to the interruption (``rerun rrd verify`` passes).
"""

from __future__ import annotations

import math
import os
import signal
import sys
import threading
import uuid
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from merger.io.overlay import PALETTE, colours_for
from merger.limits import one_line
from merger.team.defaults import verification_rule
from merger.team.online import strategy_of

from ..events import MergeCycle, Observer, RobotTick
from .entities import (
    GREY,
    circle_points,
    default_blueprint,
    dim_colour,
    entity_part,
    from_frame,
    json_block,
    known_window,
    overlay_fast,
    rr_grid_map,
    rr_transform,
    scenario_dict,
    split_geometry,
    to_frame,
)
from .parts import claim_part, release
from .viewer import has_display, rerun_executable

APP_ID = "circsim"
RRD_FOOTER_MAGIC = b"RRF2FOOT"  # the last bytes of a complete .rrd (rerun-sdk 0.41's format)
RAY_BEAM_STRIDE = 12  # rays: one beam in twelve keeps the fan readable (seen in the viewer)
SCAN_Z, MAP_Z = 0.03, -0.02  # scans above the maps; local maps stacked below z = 0 so they do not z-fight
VIEWER_PORT = 9876  # gRPC port of the viewer that ``spawn=True`` starts (rerun's default)
FLUSH_TIMEOUT_S = 30.0
POSE_BATCH_S = 1.0  # simulated seconds of poses sent at once (a live viewer lags by as much)
_LEVELS = {"debug": "DEBUG", "info": "INFO", "warn": "WARN", "warning": "WARN", "error": "ERROR"}
class RecordingError(ValueError):
    """The recording cannot be written (one line naming the file)."""


ATTACH_TIMEOUT_S = 10.0  # setting the file sink takes milliseconds; rerun 0.41 blocks forever when its writer dies
DISCONNECT_TIMEOUT_S = 30.0  # closing after the flush: the same block when the writer died during the run


def _within(fn, timeout_s: float) -> None:
    """Run ``fn`` in a daemon thread; re-raise its exception, or TimeoutError when it has not returned after
    ``timeout_s`` (it is left blocked: the caller must not wait for it again, nor for rerun at exit)."""
    box: dict = {}

    def run():
        try:
            fn()
        except BaseException as e:  # noqa: BLE001 - handed to the caller
            box["error"] = e

    t = threading.Thread(target=run, name="rerun-attach", daemon=True)
    t.start()
    t.join(timeout_s)
    if t.is_alive():
        raise TimeoutError
    if "error" in box:
        raise box["error"]


def verdict_series(cfg, checks: dict) -> list[tuple[str, float, object]]:
    """The plot of a cycle's checks: "ν" per pair against ν_min when the rule verifies on whole maps
    (``whole_map``, ``contrast`` and ``auto``: the checks hold ω̃ of the whole maps), "score" against
    score_min for ``roi_score`` (the checks hold the search's ROI score)."""
    whole = verification_rule(cfg.verification).whole_maps
    return [(f"ν {k}" if whole else f"score {k}", v.nu, None) for k, v in checks.items()] + \
        [("ν_min" if whole else "score_min", cfg.nu_min if whole else cfg.score_min, GREY)]


class RerunRecorder(Observer):
    """Records a run with rerun: live viewer, ``.rrd`` file, or both.

    Parameters
    ----------
    path : ``.rrd`` file to write (``circsim run --rrd``); its directory must exist.
    spawn : stream to a newly spawned native viewer (``--spawn``; needs a display).
    scan_log_hz : laser scans logged per simulated second (every tick would dominate the run time).
    rays_every : rays are logged with every ``rays_every``-th logged scan (0: never).
    merged_log_period_s : minimum simulated time between two logged merged maps/overlays of a robot;
        ``None``: the scenario's SLAM publish period; 0: every accepted merge.
    strict : if not ``None``, set rerun's (process-wide) strict mode: ``True`` raises on bad data (tests),
        the default (``False``) warns and drops it.
    """

    def __init__(self, path: str | os.PathLike | None = None, spawn: bool = False, scan_log_hz: float = 2.0,
                 rays_every: int = 5, *, merged_log_period_s: float | None = None,
                 strict: bool | None = None) -> None:
        if path is None and not spawn:
            raise ValueError("RerunRecorder: give an .rrd path, spawn=True, or both")
        if path is not None:
            p = Path(path)
            if p.suffix != ".rrd":
                raise ValueError(f"{p}: a rerun recording must end in .rrd")
            if not p.parent.is_dir():
                raise ValueError(f"{p}: directory {p.parent} does not exist")
        if spawn and not has_display():
            if path is None:
                raise ValueError("--spawn needs a display ($DISPLAY/$WAYLAND_DISPLAY unset): record with "
                                 "--rrd RUN.rrd and open it with `circsim view RUN.rrd --web`")
            print("circsim: no display, --spawn ignored; recording to the file only", file=sys.stderr)
            spawn = False
        if not scan_log_hz > 0:
            raise ValueError(f"scan_log_hz must be > 0, got {scan_log_hz}")
        self.path = None if path is None else str(path)
        self.part: str | None = None  # the temporary file the recording is written to, renamed at the end
        self._part_fd: int | None = None  # held open while the part is ours: its lock (circsim.record.parts)
        self.stuck = False  # rerun blocked for good starting or closing the file (the process must not wait for it)
        self.write_error: str | None = None  # why the recording could not be completed (one line), if so
        self.spawn = spawn
        self.scan_period_s = 1.0 / float(scan_log_hz)
        self.rays_every = int(rays_every)
        self.merged_log_period_s = merged_log_period_s
        if strict is not None:
            rr.set_strict_mode(strict)
        self.rec: rr.RecordingStream | None = None

    # --- run hooks -----------------------------------------------------------------------------------
    def on_start(self, sim) -> None:
        sc = sim.scenario
        self.names = list(sim.robot_names)
        self.colours = {n: occ for n, (occ, _) in zip(self.names, colours_for(self.names), strict=True)}
        self.merger_cfg = sc.merger
        self.arc_of = getattr(sim, "arc_deg", None)
        self.merged_period_s = float(sc.slam.publish_period_s if self.merged_log_period_s is None
                                     else self.merged_log_period_s)
        self.step = 0
        self.next_scan_s = 0.0
        self.scans_logged = 0
        self.published = dict.fromkeys(self.names, 0)
        self.merged_next_s = dict.fromkeys(self.names, -math.inf)
        self.merged_pending: dict[str, tuple[int, MergeCycle]] = {}
        self.series: dict[str, tuple[str, ...]] = {}
        self.colours_of: dict[tuple[str, str], tuple] = {}  # (plot, series) -> colour, fixed once declared
        self.centers_logged: dict[str, tuple[float, float]] = {}
        self.ambiguous_logged: dict[tuple[str, str, str], tuple] = {}  # (robot, ref, moving) -> last logged
        self.start_poses = {n: tuple(float(v) for v in sim.start_poses[n][:3]) for n in self.names}
        self.centers_given = {n: tuple(map(float, sim.centers_given[n])) for n in self.names}
        self.poses: dict[str, list[tuple]] = {n: [] for n in self.names}
        self.pose_batch_t0: float | None = None

        self.rec = rec = rr.RecordingStream(APP_ID, recording_id=str(uuid.uuid4()))
        bp = default_blueprint(self.names, sim.center_world, sim.centers_given)
        self._attach_sinks(bp)
        rec.send_recording_name(f"{sc.name} seed {sim.seed}")
        self._log_static_world(sim)
        rec.log("run/scenario", rr.TextDocument(json_block(scenario_dict(sc)), media_type="text/markdown"),
                static=True)
        self._at(0.0, 0)
        pairs = zip(self.names, colours_for(self.names), strict=True)
        legend = "; ".join(f"{n} occupied {occ} / free {free}" for n, (occ, free) in pairs)
        self._text("sim", "INFO", f"run of {sc.name} (seed {sim.seed}), robots {', '.join(self.names)}; "
                                  f"overlay colours (RGB): {legend}")

    def on_tick(self, t: float, step: int, ticks: list[RobotTick]) -> None:
        self._flush_pending(t)
        self._at(t, step)
        for k in ticks:  # poses go out in columns every POSE_BATCH_S: one rr.log per pose costs ~0.4 ms
            self.poses[k.name].append((t, step, *k.true_pose, *k.est_pose))
        self.pose_batch_t0 = t if self.pose_batch_t0 is None else self.pose_batch_t0
        if t - self.pose_batch_t0 + 1e-9 >= POSE_BATCH_S:
            self._flush_poses()
        if t + 1e-9 >= self.next_scan_s:
            self.next_scan_s = max(self.next_scan_s + self.scan_period_s, t)
            rays = self.rays_every > 0 and self.scans_logged % self.rays_every == 0
            self.scans_logged += 1
            for k in ticks:
                self._log_scan(k, rays)

    def on_map_published(self, t, robot, grid, center_given, center_true) -> None:
        self._at(t, self.step)
        self.published[robot] += 1
        i = self.names.index(robot)
        self.rec.log(f"world/robots/{entity_part(robot)}/map/local", rr_grid_map(grid, MAP_Z * (i + 1)))
        self.centers_given[robot] = tuple(map(float, center_given))
        if self.centers_logged.get(robot) != tuple(center_given):
            self._log_center(robot, center_given, center_true)
        c = grid.count()
        self._text(robot, "DEBUG", f"published map #{self.published[robot]} ({c['occupied']} occupied, "
                                   f"{c['free']} free cells)")

    def on_map_received(self, t, recipient, sender, sent_s, stale=False) -> None:
        self._at(t, self.step)
        self._text(recipient, "DEBUG", f"received {sender}'s map sent at {sent_s:.2f} s "
                                       f"(delay {t - sent_s:.3f} s)"
                                       + ("; stale (a newer one had arrived): dropped" if stale else ""))

    def on_merge_cycle(self, c: MergeCycle) -> None:
        self._at(c.t, self.step)
        n, res = c.robot, c.result
        self._plot_cycle(c)
        self._log_ambiguous(c)
        top = res.top
        thetas = ", ".join(f"{k} {v:.1f}°" for k, v in top.theta_deg.items() if k != n)
        nus = ", ".join(f"{k} {v:.3f}" for k, v in top.nu.items())
        errs = ", ".join(f"{k} {v:.2f}°" for k, v in c.angle_error_deg.items() if k != n)
        order = ",".join(top.order)
        if res.accepted:
            verdict = "FALSE MERGE" if c.false_merge else "correct"
            tr = ", ".join(f"{k} ({x:+.3f}, {y:+.3f}) m" for k in top.theta_deg if k != n
                           for x, y in [top.translation(k)])
            t_errs = ", ".join(f"{k} {100 * v:.1f} cm" for k, v in c.translation_error_m.items() if k != n)
            what = f"adopted {c.adopted_from}'s hypothesis" if c.adopted_from else f"accepted merge (order {order})"
            self._text(n, "ERROR" if c.false_merge else "INFO",
                       f"{what}: θ {thetas}; t {tr}; ν {nus}; angle error {errs}"
                       + (f"; translation error {t_errs}" if t_errs else "") + f" → {verdict}")
            self._log_placed_centers(c)
            if c.first_pair_correct and not c.first_correct:
                held = ", ".join(k for k in top.theta_deg if k != n)
                self._text(n, "INFO", f"FIRST CORRECT PAIR MERGE (partial team: {held}) at {c.t:.1f} s")
            if c.first_correct:
                arc = f", arc {self.arc_of(n, c.t):.1f}°" if self.arc_of else ""
                self._text(n, "INFO", f"FIRST CORRECT MERGE of all maps at {c.t:.1f} s{arc}")
            force = c.first_correct or c.false_merge or self.merged_next_s[n] == -math.inf
            if force or c.t + 1e-9 >= self.merged_next_s[n]:
                self._log_merged(c, self.step, c.t)
            else:
                self.merged_pending[n] = (self.step, c)
        else:
            note = " (this hypothesis was correct)" if c.correct else ""
            self._text(n, "INFO", f"rejected merge: best order {order}, θ {thetas}; ν {nus}: "
                                  f"{res.reason}{note}")

    def _log_ambiguous(self, c: MergeCycle) -> None:
        """One event per ambiguous pair of the cycle (both angles, scores and ν, the verdict), logged when
        it first appears or changes: a pair reused between cycles is not repeated."""
        for a in c.result.ambiguous:
            key = (c.robot, a.ref, a.moving)
            state = (round(a.best.theta_deg, 1), round(a.runner_up.theta_deg, 1), a.verdict)
            if self.ambiguous_logged.get(key) == state:
                continue
            self.ambiguous_logged[key] = state
            self._text(c.robot, "INFO" if a.used else "WARN", a.describe())

    def on_hypothesis(self, t, recipient, adoption) -> None:
        """A received hypothesis: refused ones as a DEBUG line with the reason (an adopted one is logged
        by the merge-cycle event that follows it, judged against ground truth)."""
        if adoption.adopted:
            return
        self._at(t, self.step)
        self._text(recipient, "DEBUG", f"refused {adoption.sender}'s hypothesis: {adoption.reason}")

    def on_event(self, t: float, level: str, text: str) -> None:
        self._at(t, self.step)
        self._text("sim", _LEVELS.get(level.lower(), "INFO"), text)

    def on_end(self, result) -> None:
        if self.rec is None:
            return
        step = self.step
        self._flush_poses()
        self._flush_pending(math.inf)
        d = result.to_dict()
        self._at(d["sim_s"], step)
        firsts = ", ".join(f"{n} {'—' if r['first_merge_s'] is None else format(r['first_merge_s'], '.1f') + ' s'}"
                           for n, r in d["robots"].items())
        state = "INTERRUPTED (Ctrl-C)" if d["interrupted"] else "finished"
        self._text("sim", "WARN" if d["interrupted"] else "INFO",
                   f"run {state} at {d['sim_s']:.1f} s simulated ({d['wall_s']:.1f} s wall): first correct "
                   f"merges {firsts}; false merges {d['false_merges']}; rejected correct {d['rejected_correct']}")
        self.rec.log("run/metrics", rr.TextDocument(json_block(d), media_type="text/markdown"), static=True)
        self.close()

    def close(self) -> None:
        """Flush and close every sink (writes the .rrd footer); a second Ctrl-C cannot cut it short."""
        if self.rec is None:
            return
        rec, self.rec = self.rec, None
        main = threading.current_thread() is threading.main_thread()
        old = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
        flush_error = None
        try:
            try:
                rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
            except RuntimeError as e:  # e.g. the live viewer was closed: the file sink is unaffected
                flush_error = e
            try:
                _within(rec.disconnect, DISCONNECT_TIMEOUT_S)
            except TimeoutError:  # rerun's file writer died during the run (a full disk): it never returns
                self.stuck = True
                if self.part:
                    os.unlink(self.part)
                    self.part = None
                self.write_error = (f"{self.path}: cannot write the recording (rerun's file writer stopped; a "
                                    "full disk?); nothing replaced")
                return
            self._place_recording()
            if flush_error is not None and self.write_error is None:  # (a failed file: its own error line)
                print(f"circsim: rerun: {flush_error}", file=sys.stderr)
        finally:
            release(self._part_fd)
            self._part_fd = None
            if main:
                signal.signal(signal.SIGINT, old)

    def _place_recording(self) -> None:
        """Rename the finished temporary recording into place, or, when it is incomplete (rerun's file
        writer failed: a full disk, a quota), delete it, leave whatever was at the path before untouched and
        set :attr:`write_error`. The footer is what ``rerun rrd verify`` checks first."""
        part, self.part = self.part, None
        if part is None:
            return
        try:
            size = os.path.getsize(part)
            with open(part, "rb") as f:
                f.seek(max(0, size - 64))
                complete = RRD_FOOTER_MAGIC in f.read()
            if not complete:
                raise OSError(28, "the recording is incomplete (no footer; a full disk?)")
            mask = os.umask(0)
            os.umask(mask)
            os.chmod(part, 0o666 & ~mask)
            os.replace(part, self.path)
        except OSError as e:
            self.write_error = f"{self.path}: cannot write the recording ({e.strerror or e}); nothing replaced"
            try:
                os.unlink(part)
            except OSError:
                pass

    # --- pieces --------------------------------------------------------------------------------------
    def _attach_sinks(self, bp: rrb.Blueprint) -> None:
        rec = self.rec
        url = f"rerun+http://127.0.0.1:{VIEWER_PORT}/proxy"
        if self.spawn:  # the bundled viewer: rr.spawn alone searches $PATH, which may lack the venv
            rr.spawn(port=VIEWER_PORT, connect=False, recording=rec, executable_path=rerun_executable())
        if self.path:  # written to a temporary file beside it, renamed when complete (close)
            self.part, self._part_fd = claim_part(self.path)  # a killed run's stale parts removed first
        def attach():
            if self.spawn and self.path:
                rec.set_sinks(rr.FileSink(self.part), rr.GrpcSink(url), default_blueprint=bp)
            elif self.path:
                rec.save(self.part, default_blueprint=bp)
            else:
                rec.connect_grpc(url, default_blueprint=bp)

        try:
            _within(attach, ATTACH_TIMEOUT_S)
        except TimeoutError:  # rerun's file writer died while the sink was set (a full disk): it never returns
            self.stuck = True
            self.rec = None
            if self.part:
                os.unlink(self.part)
                self.part = None
            release(self._part_fd)
            raise RecordingError(f"{self.path}: cannot write the recording (rerun's file writer stopped; a full "
                                 "disk?)") from None
        except RuntimeError as e:  # e.g. "Failed to write: No space left on device"
            if self.part:
                os.unlink(self.part)
                self.part = None
            release(self._part_fd)
            self.rec = None
            try:
                rec.disconnect()  # drop what the stream buffered (no warning about it at exit)
            except RuntimeError:
                pass
            raise RecordingError(f"{self.path}: cannot write the recording ({one_line(str(e))})") from None

    def _at(self, t: float, step: int) -> None:
        self.step = step
        self.rec.set_time("sim_time", duration=float(t))
        self.rec.set_time("step", sequence=int(step))

    def _text(self, who: str, level: str, text: str) -> None:
        self.rec.log(f"events/{entity_part(who)}", rr.TextLog(text, level=level))

    def _series(self, path: str, series: list[tuple[str, float, tuple | None]]) -> None:
        """Log one value per named series. The names (and colours) are declared once, statically; later
        values are put in the declared order (a hypothesis lists its maps in its merge order). A name not
        yet declared (a partial team's cycle, then a fuller one) is appended, so earlier values keep their
        labels; a declared name without a value is logged as NaN (a gap)."""
        values = {name: v for name, v, _ in series}
        declared = self.series.get(path, ())
        if not set(values) <= set(declared):  # new names go last: earlier values keep their labels
            known = set(declared)
            declared = self.series[path] = declared + tuple(n for n in values if n not in known)
            given = {name: col for name, _, col in series}
            colours = [self.colours_of.setdefault((path, name), given.get(name) or PALETTE[i % len(PALETTE)])
                       for i, name in enumerate(declared)]
            self.rec.log(path, rr.SeriesLines(names=list(declared), colors=colours), static=True)
        self.rec.log(path, rr.Scalars(np.array([values.get(name, math.nan) for name in declared], np.float64)))

    def _log_static_world(self, sim) -> None:
        rec, sc = self.rec, sim.scenario
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        walls, pillars, objects = split_geometry(sc, sim.world.geometry())
        rec.log("world/walls", rr.LineStrips3D(walls, colors=[(120, 120, 120)], radii=0.03), static=True)
        rec.log("world/pillars", rr.LineStrips3D(pillars, colors=[(255, 140, 0)], radii=0.015), static=True)
        rec.log("world/objects", rr.LineStrips3D(objects, colors=[(0, 200, 255)], radii=0.01), static=True)
        cx, cy = sim.center_world
        rec.log("world/center", rr.Points3D([[cx, cy, SCAN_Z]], radii=0.06, colors=[(255, 255, 255)],
                                            labels=["center"]), static=True)
        body = float(sc.robots.body_radius_m)
        for n in self.names:
            col, p = self.colours[n], f"world/robots/{entity_part(n)}"
            rec.log(f"{p}/circle", rr.LineStrips3D([circle_points(cx, cy, sim.circle_radius)], colors=[col],
                                                   radii=0.005), static=True)
            rec.log(f"{p}/pose", rr.Arrows3D(vectors=[[0.35, 0, 0]], colors=[col], labels=[n], radii=0.025),
                    rr.LineStrips3D([circle_points(0.0, 0.0, body)], colors=[col], radii=0.01), static=True)
            s = sim.start_poses[n]
            rec.log(f"{p}/map", rr_transform(s[0], s[1], s[2]), static=True)
            rec.log(f"{p}/map/slam_pose", rr.Arrows3D(vectors=[[0.3, 0, 0]], colors=[dim_colour(col)], radii=0.02,
                                                      labels=[f"{n} (SLAM)"]), static=True)
            c_true = to_frame(sim.center_world, s)
            self._log_center(n, sim.centers_given[n], c_true)

    def _log_center(self, robot: str, given, true) -> None:
        err = math.hypot(given[0] - true[0], given[1] - true[1])
        self.centers_logged[robot] = tuple(given)
        label = f"{robot}'s center (error {err * 100:.1f} cm)"
        self.rec.log(f"world/robots/{entity_part(robot)}/map/center_given",
                     rr.Points3D([[given[0], given[1], SCAN_Z]], radii=0.05, colors=[self.colours[robot]],
                                 labels=[label]), static=True)
        gx, gy = from_frame(given, self.start_poses[robot])
        self.rec.log(f"world/robots/{entity_part(robot)}/centers/given",
                     rr.Points3D([[gx, gy, SCAN_Z]], radii=0.05, colors=[self.colours[robot]], labels=[label]),
                     static=True)

    def _log_placed_centers(self, c: MergeCycle) -> None:
        """Where robot i's accepted alignment puts each teammate's given center (c_i + t_ij in M_i), in W,
        and the segment to where that center truly is (its length is the translation error)."""
        n, top = c.robot, c.result.top
        pose, (cx, cy) = self.start_poses[n], self.centers_given[n]
        mates = [k for k in top.theta_deg if k != n and k in self.centers_given]
        if not mates:
            return
        placed, strips, labels = [], [], []
        for k in mates:
            tx, ty = top.translation(k)
            px, py = from_frame((cx + tx, cy + ty), pose)
            qx, qy = from_frame(self.centers_given[k], self.start_poses[k])
            placed.append([px, py, SCAN_Z])
            strips.append([[px, py, SCAN_Z], [qx, qy, SCAN_Z]])
            err = c.translation_error_m.get(k)
            labels.append(f"{k}'s center placed by {n}" + ("" if err is None else f" (off {100 * err:.1f} cm)"))
        colours = [self.colours.get(k, GREY) for k in mates]
        base = f"world/robots/{entity_part(n)}/centers"
        self.rec.log(f"{base}/placed", rr.Points3D(placed, radii=0.035, colors=colours, labels=labels))
        self.rec.log(f"{base}/placed_error", rr.LineStrips3D(strips, colors=colours, radii=0.008))

    def _log_scan(self, k: RobotTick, rays: bool) -> None:
        x, y, yaw = k.true_pose
        c, s = math.cos(yaw), math.sin(yaw)
        pts = k.scan.points()  # laser frame = robot frame
        w = np.empty((len(pts), 3), np.float32)
        w[:, 0] = x + c * pts[:, 0] - s * pts[:, 1]
        w[:, 1] = y + s * pts[:, 0] + c * pts[:, 1]
        w[:, 2] = SCAN_Z
        p, col = f"world/robots/{entity_part(k.name)}", self.colours[k.name]
        self.rec.log(f"{p}/scan", rr.Points3D(w, colors=[col], radii=0.02))
        if rays:
            ends = w[::RAY_BEAM_STRIDE]
            strips = np.empty((len(ends), 2, 3), np.float32)
            strips[:, 0] = (x, y, SCAN_Z)
            strips[:, 1] = ends
            self.rec.log(f"{p}/rays", rr.LineStrips3D(strips, colors=[(*col, 90)], radii=0.003))

    def _plot_cycle(self, c: MergeCycle) -> None:
        """One entity per plot, one series per value (batched: one rr.log per plot and cycle)."""
        n, res, cfg = c.robot, c.result, self.merger_cfg
        base = f"plots/{entity_part(n)}"
        omega = []
        for o in res.orders:
            for k, (moving, al) in enumerate(o.steps, 1):
                if strategy_of(getattr(cfg, "strategy", "orders"), len(self.names)).pairs:
                    # the pair searches of the tree's edges
                    omega.append((f"{al.measure} tree edge {k}", al.score, None))
                    continue
                onto = o.order[0] if moving == o.order[1] else "+".join(o.order[:o.order.index(moving)])
                omega.append((f"{al.measure} {moving}→{onto}", al.score, None))
        if omega:  # an adopted hypothesis (shared) has no searches of the robot's own
            self._series(f"{base}/omega", omega)
        top = res.top
        self._series(f"{base}/nu", verdict_series(cfg, top.checks))
        self._series(f"{base}/support", [(f"support {k}", v.support, None) for k, v in top.checks.items()]
                     + [("min_support", cfg.min_support, GREY)])
        if res.accepted:
            self._series(f"{base}/angle_error_deg", [(f"{m} angle error (°)", e, self.colours.get(m))
                                                     for m, e in c.angle_error_deg.items() if m != n]
                         + [(f"{m} vs SLAM frames (°)", e, dim_colour(self.colours.get(m, GREY)))
                            for m, e in c.est_angle_error_deg.items() if m != n])
            t_errs = [(f"{m} translation error (m)", e, self.colours.get(m))
                      for m, e in c.translation_error_m.items() if m != n] \
                + [(f"{m} vs SLAM frames (m)", e, dim_colour(self.colours.get(m, GREY)))
                   for m, e in c.est_translation_error_m.items() if m != n]
            if t_errs:
                self._series(f"{base}/translation_error_m", t_errs)
        if not c.adopted_from:
            self._series(f"{base}/cycle_ms", [(f"{n} merge cycle (ms)", res.cost_ms, self.colours[n])])
        self._series(f"{base}/teammates_placed", [("teammates placed correctly", c.teammates_placed, GREY),
                                                  ("maps merged", len(res.top.theta_deg), None),
                                                  ("ambiguous pairs not used",
                                                   sum(not a.used for a in res.ambiguous), None)])

    def _log_merged(self, c: MergeCycle, step: int, now: float) -> None:
        n, res = c.robot, c.result
        self._at(c.t, step)
        self.merged_pending.pop(n, None)
        self.merged_next_s[n] = now + self.merged_period_s
        self.rec.log(f"world/robots/{entity_part(n)}/map/merged", rr_grid_map(res.merged, 0.0))
        names = [n] + [k for k in res.layers if k != n]
        layers = [res.layers[k].states for k in names]
        rs, cs = known_window(layers)
        rgb = overlay_fast([st[rs, cs] for st in layers], names)
        self.rec.log(f"merge/{entity_part(n)}/overlay", rr.Image(np.ascontiguousarray(np.flipud(rgb))))

    def _flush_poses(self) -> None:
        self.pose_batch_t0 = None
        for n in self.names:
            rows, self.poses[n] = self.poses[n], []  # taken first: a Ctrl-C in here cannot log them twice
            if not rows:
                continue
            a = np.array(rows, np.float64)
            idx = [rr.TimeColumn("sim_time", duration=a[:, 0]), rr.TimeColumn("step", sequence=a[:, 1].astype(np.int64))]
            for path, (x, y, yaw) in ((f"world/robots/{entity_part(n)}/pose", a[:, 2:5].T),
                                      (f"world/robots/{entity_part(n)}/map/slam_pose", a[:, 5:8].T)):
                tr = np.stack([x, y, np.zeros_like(x)], axis=1)
                q = np.stack([np.zeros_like(x), np.zeros_like(x), np.sin(yaw / 2), np.cos(yaw / 2)], axis=1)
                rr.send_columns(path, indexes=idx, columns=rr.Transform3D.columns(translation=tr, quaternion=q),
                                recording=self.rec)
            self._send_pose_errors(n, idx, a)

    def _send_pose_errors(self, n: str, idx, a: np.ndarray) -> None:
        """The SLAM pose error of rows (t, step, true x y yaw in W, estimate x y yaw in M_i) as two series."""
        sx, sy, syaw = self.start_poses[n]
        c, s = math.cos(syaw), math.sin(syaw)
        dx, dy = a[:, 2] - sx, a[:, 3] - sy  # the true pose in M_i
        tx, ty, tyaw = c * dx + s * dy, -s * dx + c * dy, a[:, 4] - syaw
        cm = 100.0 * np.hypot(a[:, 5] - tx, a[:, 6] - ty)
        deg = np.abs(np.degrees((a[:, 7] - tyaw + np.pi) % (2.0 * np.pi) - np.pi))
        path = f"plots/{entity_part(n)}/slam_pose_error"
        if path not in self.series:
            self.series[path] = ("position error (cm)", "yaw error (°)")
            self.rec.log(path, rr.SeriesLines(names=list(self.series[path]),
                                              colors=[self.colours[n], dim_colour(self.colours[n])]), static=True)
        rr.send_columns(path, indexes=idx, columns=rr.Scalars.columns(scalars=np.stack([cm, deg], axis=1)),
                        recording=self.rec)

    def _flush_pending(self, t: float) -> None:
        for n in list(self.merged_pending):
            step, c = self.merged_pending[n]
            if t + 1e-9 >= self.merged_next_s[n]:
                self._log_merged(c, step, t)
