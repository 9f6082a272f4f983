"""Ambiguous pairs (issue 10, item 5): a pair's best alignment and its runner-up (more than 10° apart) score
within the margin; the pair is used only when whole-map ν separates the two. Checked against ground truth."""

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from merger.search import angle_diff_deg
from merger.synthetic import arc_viewpoints, partial_view, room_scene, window_case
from merger.team.ambiguity import verdict
from merger.team.frames import Warps
from merger.team.orders import MapInput, MergeParams, merge_team
from merger.team.tree import merge_tree, pair_result

P = MergeParams(roi_m=8.0, window_m=0.5)  # margin 0.05 (the default with a window)


# The reference map's name comes first: the strategies search a pair with that map as the reference
# (merger.team.orders.merge_orders ranks maps by name; merger.team.tree the same), and ambiguity is a property of
# the search in that direction.
def case_maps(c, names=("Auckland", "Lyon")):
    return [MapInput(names[0], c.ref, c.center_ref), MapInput(names[1], c.moving, c.center_moving)]


def near(a, b, tol):
    return abs(angle_diff_deg(a, b)) <= tol


# Seeds of the point-symmetric room (two pillars, no boxes, short arcs) whose two views keep the truth and
# its half turn within the margin, and whose walls do not tell them apart either (measured: ν within 0.04).
SYMMETRIC_UNRESOLVED = [0, 1, 5, 7]


@pytest.mark.parametrize("seed", SYMMETRIC_UNRESOLVED)
def test_a_point_symmetric_pair_is_ambiguous_with_both_angles_and_not_used(seed):
    c = window_case(seed, "symmetric", roi_m=(8.0, 8.0), window_m=(0.5, 0.5))
    maps = case_maps(c)
    pr = pair_result(maps, 0, 1, P, Warps(maps))
    a = pr.ambiguity
    assert pr.ambiguous and a is not None and a.verdict == "unresolved" and not a.used
    angles = (a.best.theta_deg, a.runner_up.theta_deg)
    # one hypothesis is the truth, the other its half turn (each within 1°), in either order
    assert any(near(x, c.theta_deg, 1.0) and near(y, c.theta_deg + 180.0, 1.0)
               for x, y in (angles, angles[::-1])), (angles, c.theta_deg)
    # with the window on, both hypotheses carry their translation: the truth's is t*, the half turn's −t*
    truth = a.best if near(a.best.theta_deg, c.theta_deg, 1.0) else a.runner_up
    assert math.dist(truth.translation_m, c.translation_m) <= 0.1
    assert abs(a.best.score - a.runner_up.score) < P.margin and abs(a.best.nu - a.runner_up.nu) < P.margin
    # the pair is not used: its verification fails and names both angles
    assert not pr.verification.passed and "ambiguous" in pr.verification.reason
    assert f"{a.best.theta_deg:.1f}°" in pr.verification.reason
    assert f"{a.runner_up.theta_deg:.1f}°" in pr.verification.reason
    d = json.loads(json.dumps(pr.to_dict()))  # a plain serializable record
    assert d["ambiguous"] is True and d["ambiguity"]["verdict"] == "unresolved"
    assert d["ambiguity"]["theta_deg"] == [a.best.theta_deg, a.runner_up.theta_deg]
    assert d["ambiguity"]["runner_up"]["translation_m"] == list(a.runner_up.translation_m)


@pytest.mark.parametrize("seed", SYMMETRIC_UNRESOLVED[:2])
def test_both_strategies_refuse_an_unresolved_pair(seed):
    c = window_case(seed, "symmetric", roi_m=(8.0, 8.0), window_m=(0.5, 0.5))
    orders = merge_team(case_maps(c), P)
    assert not orders.accepted and "ambiguous pair Auckland←Lyon" in orders.reason
    assert [a.verdict for a in orders.ambiguous] == ["unresolved"]
    tree = merge_tree(case_maps(c), P)
    assert not tree.accepted and "ambiguous pair Auckland←Lyon" in tree.reason  # the only edge is dropped
    assert [a.verdict for a in tree.ambiguous] == ["unresolved"]
    json.dumps(orders.to_dict()) and json.dumps(tree.to_dict())
    # the rule off (margin 0, the thesis's rule): the same pair is used, true or half-turned
    off = merge_team(case_maps(c), MergeParams(roi_m=8.0, window_m=0.5, ambiguity_margin=0.0))
    assert off.ambiguous == ()


@pytest.mark.parametrize("seed", range(4))
def test_an_asymmetric_pair_is_not_ambiguous(seed):
    c = window_case(seed, "views", roi_m=(8.0, 8.0), window_m=(0.5, 0.5))
    maps = case_maps(c)
    pr = pair_result(maps, 0, 1, P, Warps(maps))
    assert not pr.ambiguous and pr.to_dict()["ambiguous"] is False
    assert pr.verification.passed and near(pr.alignment.theta_deg, c.theta_deg, 0.5)


@pytest.fixture(scope="module")
def pillars_in_an_offset_room():
    """Two pillars point-symmetric about the center inside a room that is not (its walls are off-center):
    a 4 m ROI sees only the pillars, whose half turn scores a little higher there than the truth; the
    whole maps (walls) tell them apart."""
    scene = room_scene(np.random.default_rng(0), n_boxes=0, room_center=(0.9, 0.5))
    theta = 63.0
    fa, fb = (0.2, -0.1, 0.3), (-0.4, 0.3, 0.3 + math.radians(theta))
    ga, ca = partial_view(scene, fa, arc_viewpoints(90, 180, 1.8, k=8))
    gb, cb = partial_view(scene, fb, arc_viewpoints(90, 180, 1.8, k=8))
    return [MapInput("Auckland", ga, ca), MapInput("Lyon", gb, cb)], theta


@pytest.mark.parametrize("window_m", [0.0, 0.5])
def test_an_ambiguous_pair_that_whole_maps_separate_is_used_and_lands_on_the_truth(pillars_in_an_offset_room,
                                                                                   window_m):
    maps, theta = pillars_in_an_offset_room
    # the pillars' half turn rests on 47 cells of ROI support: below the default support floor (50) the
    # search answers the truth directly; without the floor the ambiguity rule must find it
    params = MergeParams(roi_m=4.0, window_m=window_m, ambiguity_margin=0.05, roi_min_support=0)
    pr = pair_result(maps, 0, 1, params, Warps(maps))
    a = pr.ambiguity
    assert a is not None and a.used and a.verdict == "runner_up"
    assert near(a.best.theta_deg, theta + 180.0, 1.0) and near(a.runner_up.theta_deg, theta, 1.0)
    assert a.best.score >= a.runner_up.score  # the ROI prefers the half turn ...
    assert a.runner_up.nu - a.best.nu >= 0.05  # ... the whole maps the truth
    assert pr.verification.passed and near(pr.alignment.theta_deg, theta, 0.5)
    orders = merge_team(maps, params)
    assert orders.accepted and near(orders.chosen.theta_deg["Lyon"], theta, 0.5), orders.reason
    assert [x.verdict for x in orders.ambiguous] == ["runner_up"]
    # the tree takes the same verdict, but a pair chosen over its rival joins two maps only with a second
    # route (merger.team.consensus): two maps have none, and the tree refuses with that reason
    tree = merge_tree(maps, params)
    assert [x.verdict for x in tree.ambiguous] == ["runner_up"] and near(tree.top.theta_deg["Lyon"], theta, 0.5)
    assert not tree.accepted and "a lone ambiguous pair" in tree.reason, tree.reason
    # with the default support floor: the truth, directly (rotation only: the half turn's 47 cells are no
    # candidate) or through the rule (with the window a shifted half turn reaches the floor)
    floored = merge_team(maps, MergeParams(roi_m=4.0, window_m=window_m, ambiguity_margin=0.05))
    assert floored.accepted and near(floored.chosen.theta_deg["Lyon"], theta, 0.5), floored.reason
    # without the rule the ROI's best, the half turn, is the pair's answer and fails verification
    off = merge_team(maps, MergeParams(roi_m=4.0, window_m=window_m, ambiguity_margin=0.0, roi_min_support=0))
    assert not off.accepted and near(off.top.theta_deg["Lyon"], theta + 180.0, 1.0)


def test_a_chosen_hypothesis_followed_locally_is_still_a_choice(pillars_in_an_offset_room):
    """The tracker follows the tree's verified pairs with local searches, which have no runner-up: the
    hypothesis whole-map ν chose over its rival stays a choice while it is followed (the track keeps the
    ambiguity record), so a later cycle cannot join it alone where the first could not."""
    import dataclasses

    from merger.team.track import Tracker

    maps, theta = pillars_in_an_offset_room
    params = MergeParams(roi_m=4.0, window_m=0.5, ambiguity_margin=0.05, roi_min_support=0)
    tracker = Tracker()
    first = merge_tree(maps, params, tracker=tracker, now=0.0)
    assert not first.accepted and [x.verdict for x in first.ambiguous] == ["runner_up"]
    track = tracker.tracks["Auckland|Lyon"]
    assert track.chosen is not None and (track.globals, track.locals) == (1, 0)
    again = merge_tree([dataclasses.replace(m, version=2) for m in maps], params, tracker=tracker, now=1.0)
    # followed, not searched again: the same grids again, so the tree holds its answer (a local search when they change)
    assert (track.globals, track.locals + track.holds) == (1, 1)
    assert near(again.top.theta_deg["Lyon"], theta, 0.5)
    assert not again.accepted and "a lone ambiguous pair" in again.reason, again.reason
    assert [x.verdict for x in again.ambiguous] == ["runner_up"]


def test_verdict_needs_the_margin_either_way():
    assert verdict(0.70, 0.64, 0.05) == "best"
    assert verdict(0.60, 0.66, 0.05) == "runner_up"
    assert verdict(0.70, 0.66, 0.05) == "unresolved"
    assert verdict(0.66, 0.70, 0.05) == "unresolved"


def test_the_recording_shows_each_ambiguous_pair_once(tmp_path):
    """A cycle's ambiguous pair is a text event of the merging robot naming both angles (logged once while
    it is unchanged), read back from the .rrd."""
    from circsim.config.scenario import bundled_scenarios, load_scenario
    from circsim.events import MergeCycle
    from circsim.record.entities import to_frame
    from circsim.record.rerun import RerunRecorder
    from circsim.record.viewer import read_recording
    from circsim.world.motion import trajectories
    from circsim.world.world import World

    sc = load_scenario(bundled_scenarios()["scene1"])
    names = list(sc.robots.names)
    trajs = trajectories(sc)
    start = {n: trajs[n].start_pose() for n in names}
    sim = SimpleNamespace(scenario=sc, world=World.from_scenario(sc), robot_names=names, start_poses=start,
                          centers_given={n: to_frame(sc.world.center, start[n]) for n in names},
                          center_world=tuple(sc.world.center), circle_radius=sc.robots.radius_m, seed=sc.seed)
    c = window_case(0, "symmetric", roi_m=(8.0, 8.0), window_m=(0.5, 0.5))
    me, other = sorted(names[:2])  # Auckland, Lyon: the merging robot's map is the reference
    res = merge_team(case_maps(c, (me, other)), P)
    a = res.ambiguous[0]
    rrd = tmp_path / "amb.rrd"
    rec = RerunRecorder(rrd)
    rec.on_start(sim)
    truth = {me: 0.0, other: c.theta_deg}
    for t in (1.0, 2.0):
        rec.on_merge_cycle(MergeCycle(t, me, other, res, truth, False, {}, False, False))
    rec.on_end(SimpleNamespace(to_dict=lambda: {"robots": {}, "sim_s": 2.0, "wall_s": 0.0, "interrupted": False,
                                                 "false_merges": 0, "rejected_correct": 0}))
    ev = [r["TextLog:text"][0] for r in read_recording(rrd)[f"/events/{me}"] if not r["static"]]
    amb = [x for x in ev if x.startswith("ambiguous pair")]
    assert len(amb) == 1, ev
    assert f"θ {a.best.theta_deg:.1f}°" in amb[0] and f"θ {a.runner_up.theta_deg:.1f}°" in amb[0]
    assert "not used" in amb[0]


def _pattern_grids(shift_cells: int):
    """A reference with the same asymmetric cluster twice, ``shift_cells`` apart along x (free around),
    and a moving map holding one copy (nothing else known), both 80 × 80 cells of 5 cm, centers at the
    grids' middles; the moving copy sits 4 cells left of the reference's first copy."""
    from merger.grid import OccupancyGrid

    pattern = [(0, 0), (0, 1), (0, 2), (0, 3), (1, 0), (2, 0), (3, 0), (5, 2), (2, 5), (6, 6)]
    ref = np.full((80, 80), 1, np.uint8)
    mov = np.zeros((80, 80), np.uint8)
    for r, c in pattern:
        ref[50 + r, 44 + c] = ref[50 + r, 44 + shift_cells + c] = 2
        mov[50 + r, 40 + c] = 2
    return OccupancyGrid(ref, 0.05, (-2.0, -2.0)), OccupancyGrid(mov, 0.05, (-2.0, -2.0))


def test_a_rival_at_the_same_angle_but_another_translation_is_weighed_by_whole_map_evidence():
    """Two equally good translations 0.35 m apart at the same angle (the angle rival cannot see them): the
    search returns the one nearer the given center, :func:`shift_rival` the other, exactly; resolve() lets
    whole-map ν choose — and without a window there is no translation rival."""
    from merger.measures import Counts
    from merger.search import RotationProblem, search
    from merger.team.ambiguity import resolve, shift_rival
    from merger.team.verify import Verification

    ref, mov = _pattern_grids(7)
    prob = RotationProblem(ref, mov, (0.0, 0.0), (0.0, 0.0), 3.0, "similarity", 0.5, False)
    al = search(prob, "fast")
    # a small cluster: every angle within a few degrees puts its cells on the copy (a plateau of 1.0)
    assert al.score == 1.0 and abs(angle_diff_deg(al.theta_deg, 0.0)) <= 5.0
    assert abs(al.translation_m[0] - 0.2) <= 0.051 and abs(al.translation_m[1]) <= 0.051  # the nearer copy
    riv = shift_rival(prob, al, 0.05)
    assert riv is not None and riv.score == 1.0 and abs(angle_diff_deg(riv.theta_deg, al.theta_deg)) <= 2.0
    # the other copy, 7 cells (0.35 m) further along x, within a cell
    assert abs(riv.translation_m[0] - al.translation_m[0] - 0.35) <= 0.051 and abs(riv.translation_m[1]) <= 0.051
    assert riv.counts == prob.at(*riv.cells).evaluate(riv.theta_deg).counts  # exact, as the search's own

    def nu_of(a):  # whole-map evidence that prefers the far copy
        nu = 0.9 if a.translation_m[0] > 0.4 else 0.6
        return Verification(nu, Counts(500, 10), True)

    chosen, amb = resolve(prob, al, 0.05, nu_of, "ref", "mov")
    assert amb is not None and amb.verdict == "runner_up"
    assert chosen.translation_m == riv.translation_m and chosen.theta_deg == riv.theta_deg
    assert shift_rival(prob, al, 0.0) is None
    flat = RotationProblem(ref, mov, (0.0, 0.0), (0.0, 0.0), 3.0, "similarity", 0.0, False)
    assert shift_rival(flat, search(flat, "fast"), 0.05) is None


def test_a_single_copy_has_no_translation_rival():
    """With one copy in the reference, every translation more than 0.2 m away scores far below the best."""
    from merger.search import RotationProblem, search
    from merger.team.ambiguity import shift_rival

    ref, mov = _pattern_grids(0)
    prob = RotationProblem(ref, mov, (0.0, 0.0), (0.0, 0.0), 3.0, "similarity", 0.5, False)
    al = search(prob, "fast")
    assert al.score == 1.0 and abs(al.translation_m[0] - 0.2) <= 0.051
    assert shift_rival(prob, al, 0.05) is None
