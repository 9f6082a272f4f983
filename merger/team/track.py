"""Online merging that follows its answers (issue 33): re-verify every map version, search globally when needed.

With ``research: every_version`` (the thesis's behaviour) every new map version is searched globally. With
``research: on_change`` (the default) a pair that holds an accepted answer is first *re-verified* at each
new map version: an exact local search about the answer (:func:`merger.search.local.local_search`: a few
degrees and cells around it, the same measure and refinement) and the whole-map verification. If that
passes, and its ν has not fallen by more than ``research_drop`` below the ν of the last global search,
it is the pair's answer. A global search runs instead (the first merge of a pair is always the global
search's answer) when

(a) the local answer fails verification, or its evidence falls by more than ``research_drop``, or it lies
    more than SAME_HYPOTHESIS_DEG / _M from the track's *anchor* (where the tracked answer was found: a
    global search's placement, or the team's): ±3 cells a version, the local optimum can walk along a
    bare hall's flat ridge metres away, every step verifying (generated floor plan 28: 0.53 then 0.70 m);
(b) either map's region of interest changed by more than ``research_change`` (the fraction of its known
    cells whose state changed; the cells on the team's ring, where the teammates' bodies move on at every
    version, are left out: :meth:`Tracker.roi`) since the pair's last global search;
(c) the pair was last searched globally ``research_period_s`` or more ago (the staleness bound; LINKED_PERIOD_FACTOR
    times it for a pair whose two maps the team's last accepted placement links);
(d) an earlier global search disagreed with the tracked answer (a candidate awaits confirmation), or
    the team's assembly refused a cycle that used the local answer (the tree: an inconsistent loop, a
    tree edge failing on map 0's frame): the pair's next version is searched globally.

With the tree (:mod:`merger.team.tree`), a new version of a pair whose answer verified is not re-verified while
neither map's ROI changed by more than HOLD_CHANGE_FACTOR × ``research_change`` since the versions that answer
was computed on (:meth:`Tracker.unchanged`): the answer holds (the maps' frames do not move; only their content
can move an answer, and the tree verifies its edges on the current maps at every cycle). The change is a
function of the two versions alone, computed once for every robot of a simulation.

A pair without an accepted answer is searched again only on (b) or (c): failed candidates are not
retried until their maps change (Swarm-SLAM, COVINS). With the tree, a pair whose last two global searches
found one answer, refused for want of whole-map support, is re-verified there on (b) (the local search) and
searched globally once that gives three quarters of ``min_support`` cells of support
(:func:`merger.team.tree.merge_tree`; the versions it waited are the ``waited`` statistic).

A global answer that agrees with the tracked one (within 10° and 0.2 m) replaces it; one that disagrees
while the tracked answer still verifies becomes a *candidate* and replaces it only when the next global
search finds it again and it verifies with a higher ν than the tracked answer on the same maps (hysteresis: m-explore's map_merge overwrites its
estimate with every new one and users see merged maps jump, hrnr/m-explore #22). A verified answer is
never dropped because one global search failed. Anchors: Cartographer searches globally only for
trajectories not connected within ``global_constraint_search_after_n_seconds`` = 10 s (our
``research_period_s`` default) and otherwise matches locally from the current relative pose
(``pose_graph.lua``, ``constraint_builder_2d.cc``).

Times are the caller's clock (the simulation's seconds); without one, each cycle counts one second.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import numpy as np

from ..grid import UNKNOWN_S
from ..jit import njit
from ..lattice import extract_roi, lattice_offsets, roi_cells
from ..search import angle_diff_deg
from .defaults import (  # noqa: F401 (the settings' defaults, merger.team.defaults: read here, and their old paths)
    RESEARCH_CHANGE,
    RESEARCH_DEFAULT,
    RESEARCH_DROP,
    RESEARCH_MODES,
    RESEARCH_PERIOD_S,
)
from .memo import map_key
from .teammates import ring

UNTRACKED_CHANGE_FACTOR = 0.25  # a pair without an accepted answer is searched again at a quarter of research_change
# (a constant: it was read from an environment variable UCF, a setting that changed results unseen)
LINKED_PERIOD_FACTOR = 3.0  # a pair the team's accepted placement links is searched globally for staleness only
# after this many research_period_s (Cartographer searches globally only for trajectories not yet connected,
# global_constraint_search_after_n_seconds; we keep a bound): in the 16-robot hall (seed 1) searches at the staleness
# bound were 425 of the 580 distinct global searches from 20 to 40 s; with linked pairs' bound 10 s, 30 s or none
# (40 s) every metric was the same
HOLD_CHANGE_FACTOR = 0.25  # a verified pair's answer holds for new versions while neither map's ROI changed by more
# than this × research_change since the versions it was computed on (the frames do not move: only the maps' content
# can move an answer). In the 8-robot hall (W 0.5 m) a map's ROI changed by a median 2.4% a version at 10–30 s and
# 0.5% after 30 s: the re-verification of every pair at every version bought nothing there
SAME_HYPOTHESIS_DEG = 10.0  # two answers this close in angle and SAME_HYPOTHESIS_M in translation are one hypothesis
SAME_HYPOTHESIS_M = 0.2  # (the ambiguity rule's distances, merger.team.orders.AMBIGUOUS_DEG / _M)


def roi_change(before: np.ndarray | None, now: np.ndarray) -> float:
    """The fraction of the ROI's known cells (known in either) whose state differs (1 without ``before``)."""
    if before is None or before.shape != now.shape:
        return 1.0
    if before.ndim != 2:
        before, now = before.reshape(1, -1), now.reshape(1, -1)
    changed, n = _changed_known(before, now)
    return float(changed) / n if n else 0.0


def roi_change_reference(before: np.ndarray | None, now: np.ndarray) -> float:
    """:func:`roi_change` in numpy (the tests compare them)."""
    if before is None or before.shape != now.shape:
        return 1.0
    known = (before != UNKNOWN_S) | (now != UNKNOWN_S)
    n = int(known.sum())
    return float((before != now).sum()) / n if n else 0.0


@njit(cache=True, nogil=True)
def _changed_known(before, now):
    """The cells whose state differs and the cells known in either, in one pass (the GIL released: the
    trackers of a simulation's robots ask it side by side)."""
    changed = known = 0
    for r in range(before.shape[0]):
        for c in range(before.shape[1]):
            x, y = before[r, c], now[r, c]
            if x != UNKNOWN_S or y != UNKNOWN_S:
                known += 1
            if x != y:
                changed += 1
    return changed, known


def placement_jump(a, b) -> tuple[float, float]:
    """(|Δθ|°, |Δt| m) between two placements (θ, (tx, ty)); of two team placements (map name → placement),
    the largest over the maps both place (inf when they place different maps)."""
    if isinstance(a, dict):
        if set(a) != set(b):
            return math.inf, math.inf
        j = [placement_jump(a[k], b[k]) for k in a] or [(0.0, 0.0)]
        return max(x[0] for x in j), max(x[1] for x in j)
    return (abs(float(angle_diff_deg(a[0], b[0]))),
            math.hypot(float(a[1][0]) - float(b[1][0]), float(a[1][1]) - float(b[1][1])))


def jump_summary(jumps) -> dict:
    """Placement jumps [(Δθ°, Δt m), ...] summarized: their count, p95 and largest of each (None: none)."""
    j = np.asarray(jumps, np.float64).reshape(-1, 2)
    if not len(j):
        return {"count": 0, "deg_p95": None, "m_p95": None, "deg_max": None, "m_max": None}
    return {"count": int(len(j)), "deg_p95": float(np.percentile(j[:, 0], 95)),
            "m_p95": float(np.percentile(j[:, 1], 95)), "deg_max": float(j[:, 0].max()),
            "m_max": float(j[:, 1].max())}


def agree(a, b) -> bool:
    """Whether two placements (or team placements) are one hypothesis: within SAME_HYPOTHESIS_DEG and SAME_HYPOTHESIS_M."""
    dth, dt = placement_jump(a, b)
    return dth <= SAME_HYPOTHESIS_DEG and dt <= SAME_HYPOTHESIS_M


@dataclass
class Track:
    """What the tracker knows of one pair (or of one robot's team hypothesis, with the orders strategy)."""

    tracked: object = None  # the accepted answer followed (an Alignment, or a team hypothesis); None: none
    placement: tuple | None = None  # its (θ, t)
    nu_ref: float = 0.0  # ν (or mean ν) of the last global search that set or confirmed it
    global_s: float = -math.inf  # when the last global search ran
    rois: dict = field(default_factory=dict)  # map name → its ROI states at the last global search
    roi_keys: dict = field(default_factory=dict)  # map name → that map version's key (merger.team.memo.map_key)
    last_rois: dict = field(default_factory=dict)  # map name → its ROI states in the versions ``last`` was computed on
    last_keys: dict = field(default_factory=dict)  # map name → those versions' keys
    candidate: tuple | None = None  # a disagreeing verified global answer (θ, t), awaiting a second global
    recheck: str = ""  # why the next version must be searched globally (the team's assembly refused it)
    last: object = None  # the last result (used again while nothing calls for a new global search)
    anchor: tuple | None = None  # the placement the tracked answer was found at (a global search, or a local
    # one about the team's placement): the local re-verifications follow it only within SAME_HYPOTHESIS_*
    chosen: object = None  # the ambiguity record of the global answer that set the anchor (whole-map ν chose it
    # over a rival, merger.team.ambiguity): its local re-verifications follow a chosen hypothesis; None: none
    last_accepted: tuple | None = None  # the last accepted placement (θ, t): for the jumps
    globals: int = 0
    locals: int = 0
    holds: int = 0  # new map versions that kept the last answer (:meth:`Tracker.unchanged`)
    answers: list = field(default_factory=list)  # the last two global searches' answers (merger.team.tree.Answer)
    waits: int = 0  # changed map versions of a never-verified pair not searched globally: too little support at
    # its answer (merger.team.tree)
    switches: int = 0
    jumps: list = field(default_factory=list)  # (Δθ°, Δt m) between consecutive accepted answers

    def near_anchor(self, placement) -> bool:
        """Whether a local answer's placement is still the hypothesis the track was found at (no anchor:
        nothing to hold it to)."""
        return self.anchor is None or agree(placement, self.anchor)


@dataclass
class Tracker:
    """The tracks of one merging robot, keyed by pair ("A|B", the reference first) or "team"; its
    settings; the events to tell (switches) and counters. Thread-safe for the pair updates of one cycle."""

    period_s: float = RESEARCH_PERIOD_S
    change: float = RESEARCH_CHANGE
    drop: float = RESEARCH_DROP
    tracks: dict = field(default_factory=dict)
    events: list = field(default_factory=list)  # (time, text): taken by the caller (take_events)
    team_place: dict = field(default_factory=dict)  # the last accepted team placement, map name → (θ, t)
    ring_m: float = 0.0  # the team ring's margin (merger.team.teammates.ring): its cells are no change
    window_m: float = 0.0  # the translation window (the ring's margin takes its half; ring_m 0: nothing left out)
    memo: object = field(default=None, repr=False)  # a merger.team.memo.Memo: the ROIs shared with teammates' trackers
    _rois: dict = field(default_factory=dict, repr=False)  # (name, version, center, n) → ROI states
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    @classmethod
    def from_params(cls, params, memo=None) -> Tracker:
        """The tracker of ``params``; with the teammates' ring seen apart (``teammate_radius_m`` or
        ``teammate_shift_m``) its ring's cells are left out of the change test (:meth:`roi`). ``memo``: the
        ROIs shared with the other robots of a simulation."""
        ring_m = params.teammate_radius_m if params.teammate_radius_m > 0 else 2 * params.teammate_shift_m
        return cls(params.research_period_s, params.research_change, params.research_drop,
                   ring_m=max(ring_m, 0.0), window_m=params.window_m, memo=memo)

    def track(self, key: str) -> Track:
        with self._lock:
            return self.tracks.setdefault(key, Track())

    def roi(self, m, roi_m: float) -> np.ndarray:
        """Map input ``m``'s ROI states about its center (kept per map version), the cells on its team's ring
        (:func:`merger.team.teammates.ring`, with ``ring_m``) unknown: the teammates' bodies move on at every
        version, and that is no change of the scene. In the 16-robot hall (seed 1) the ring held 60–70% of
        the changed cells that made pairs without an answer due for a global search again; left out, the
        robots' global searches fell only 2% (30 s: 23,756 → 23,278, the same decisions): while the maps
        grow, the rest of the ROI changes by more than the bar as well.

        With ``memo`` the ROI of a map version is computed once for every robot of the simulation (read-only):
        kept per tracker, the 32-robot hall's 32 trackers held 214 MB of them after 30 s."""
        n = roi_cells(roi_m, m.grid.resolution)
        if self.memo is not None:
            return self.memo.get(("tracker-roi", map_key(m), n, self.ring_m, self.window_m),
                                 lambda: self._roi(m, n))
        key = (m.name, m.version if m.version is not None else id(m.grid), tuple(m.center), n)
        with self._lock:
            hit = self._rois.get(key)
        if hit is None:
            hit = self._roi(m, n)
            with self._lock:
                if len(self._rois) > 256:
                    self._rois.clear()
                self._rois[key] = hit
        return hit

    def _roi(self, m, n: int) -> np.ndarray:
        """The ROI of :meth:`roi`, computed (read-only)."""
        out = extract_roi(m.grid, m.center, n)
        band = ring(m, self.ring_m, self.window_m) if self.ring_m > 0 else None
        if band is not None:
            d2 = lattice_offsets(n, m.grid.resolution) ** 2
            d2 = d2[:, None] + d2[None, :]
            out[(d2 >= band[0] ** 2) & (d2 <= band[1] ** 2)] = UNKNOWN_S
        out.flags.writeable = False
        return out

    def stale_after(self, linked: bool) -> float:
        """The staleness bound of a pair: ``period_s``, or LINKED_PERIOD_FACTOR times it when the team's last
        accepted placement links its two maps (``linked``)."""
        return self.period_s * (LINKED_PERIOD_FACTOR if linked else 1.0)

    def due(self, tr: Track, maps, roi_m: float, now: float, linked: bool = False) -> str:
        """Why a global search is due for ``tr`` over ``maps`` ("" when none is): staleness, change, candidate.
        A track without an accepted answer is due at a quarter of ``change`` (UNTRACKED_CHANGE_FACTOR); the
        staleness bound of a pair the team links is :meth:`stale_after`."""
        change = self.change if tr.tracked is not None else self.change * UNTRACKED_CHANGE_FACTOR
        if tr.candidate is not None:
            return "a disagreeing global answer awaits confirmation"
        if tr.recheck:
            return tr.recheck
        period = self.stale_after(linked)
        if now - tr.global_s >= period - 1e-9:
            return f"last global search {now - tr.global_s:.1f} s ago (staleness bound {period:g} s)"
        for m in maps:
            c = self.change_of(tr, m, roi_m)
            if c > change:
                return f"{m.name}'s ROI changed by {c:.1%} (more than {change:g})"
        return ""

    def change_of(self, tr: Track, m, roi_m: float) -> float:
        """:func:`roi_change` of map ``m``'s ROI since ``tr``'s last global search."""
        return self._change(tr.rois.get(m.name), tr.roi_keys.get(m.name), m, roi_m)

    def _change(self, before, before_key, m, roi_m: float) -> float:
        """:func:`roi_change` of map ``m``'s ROI since ``before`` (the ROI of the version keyed ``before_key``);
        with ``memo``, computed once per pair of map versions for every robot of the simulation (the robots
        ask it of the same versions)."""
        if self.memo is None or before is None or before_key is None:
            return roi_change(before, self.roi(m, roi_m))
        n = roi_cells(roi_m, m.grid.resolution)
        return self.memo.get(("tracker-roi-change", before_key, map_key(m), n, self.ring_m, self.window_m),
                             lambda: roi_change(before, self.roi(m, roi_m)))

    def snapshot(self, maps, roi_m: float) -> tuple[dict, dict]:
        """The maps' ROIs and their versions' keys, by map name: what a change is measured from."""
        return {m.name: self.roi(m, roi_m) for m in maps}, {m.name: map_key(m) for m in maps}

    def computed_on(self, tr: Track, maps, roi_m: float) -> None:
        """Record the map versions ``tr.last`` was computed on (for :meth:`unchanged`)."""
        tr.last_rois, tr.last_keys = self.snapshot(maps, roi_m)

    def unchanged(self, tr: Track, maps, roi_m: float) -> bool:
        """Whether neither map's ROI changed by more than HOLD_CHANGE_FACTOR × ``change`` since the versions
        ``tr.last`` was computed on: its answer then holds for these versions too (:mod:`merger.team.tree`)."""
        bar = self.change * HOLD_CHANGE_FACTOR
        return all(m.name in tr.last_keys and self._change(tr.last_rois[m.name], tr.last_keys[m.name], m, roi_m) <= bar
                   for m in maps)

    def searched(self, tr: Track, maps, roi_m: float, now: float) -> None:
        """Record a global search of ``tr`` over ``maps`` at ``now``."""
        tr.recheck = ""
        tr.globals += 1
        tr.global_s = now
        tr.rois, tr.roi_keys = self.snapshot(maps, roi_m)

    def accepted(self, tr: Track, placement) -> None:
        if tr.last_accepted is not None:
            tr.jumps.append(placement_jump(tr.last_accepted, placement))
        tr.last_accepted = placement

    def switched(self, key: str, tr: Track, now: float, old, new) -> None:
        tr.switches += 1
        dth, dt = placement_jump(old, new)
        with self._lock:
            self.events.append((now, f"SWITCH {key}: a global search replaced the tracked answer "
                                     f"(moved {dth:.1f}° / {dt:.2f} m)"))

    def take_events(self) -> list:
        with self._lock:
            out, self.events = self.events, []
        return sorted(out)  # in time, then text: not in the order a cycle's threads happened to finish

    def stats(self) -> dict:
        """Per track: global searches, local re-verifications, switches and its answers' jumps (:func:`jump_summary`)."""
        return {k: {"global_searches": tr.globals, "local_checks": tr.locals, "held": tr.holds,
                    "waited": tr.waits, "switches": tr.switches,
                    "jumps": jump_summary(tr.jumps)} for k, tr in sorted(self.tracks.items())}


def decide(tracker: Tracker, key: str, tr: Track, local, local_ok: bool, glob, glob_ok: bool, now: float,
           placement_of, nu_of, suspect: bool = False):
    """The answer of a cycle that ran a global search (``glob``, verified: ``glob_ok``) beside the local
    re-verification (``local``, None when no answer was tracked; ``local_ok``): see the module notes.
    Updates ``tr`` and returns the result to use. A tracked answer stays tracked (it is re-verified
    locally at the next map version) when neither verifies now. An answer the team's assembly implicated
    (``tr.recheck``: an inconsistent loop, a tree edge failing on map 0's frame) has evidence against it:
    the global search's verdict then stands, as with ``every_version`` (no hysteresis; a failed global
    search drops it)."""
    if suspect:
        if glob_ok:
            g_place = placement_of(glob)
            if tr.placement is not None and not agree(g_place, tr.placement):
                tracker.switched(key, tr, now, tr.placement, g_place)
            tr.tracked, tr.placement, tr.nu_ref, tr.candidate, tr.anchor = glob, g_place, nu_of(glob), None, g_place
            tr.chosen = getattr(glob, "ambiguity", None)
        else:
            tr.tracked, tr.placement, tr.candidate = None, None, None
        return glob
    if not glob_ok:
        if local is not None and local_ok:  # never drop a verified answer because one search failed
            tr.tracked, tr.placement, tr.candidate = local, placement_of(local), None
            return local
        return glob
    g_place = placement_of(glob)
    if local is not None and local_ok and not agree(g_place, tr.placement):
        # the global answer disagrees and the tracked one still verifies: hysteresis
        if not (tr.candidate is not None and agree(g_place, tr.candidate) and nu_of(glob) > nu_of(local)):
            tr.candidate = g_place
            tr.tracked, tr.placement = local, placement_of(local)
            return local
    if tr.placement is not None and not agree(g_place, tr.placement):
        tracker.switched(key, tr, now, tr.placement, g_place)
    tr.tracked, tr.placement, tr.nu_ref, tr.candidate, tr.anchor = glob, g_place, nu_of(glob), None, g_place
    tr.chosen = getattr(glob, "ambiguity", None)
    return glob
