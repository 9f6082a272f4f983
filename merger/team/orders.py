"""Team merging: merge orders, verification on whole maps, choice of the hypothesis (thesis 3.3.1).

The team's parameter set and value types (MergeParams, MapInput, OrderResult, TeamMergeResult, Placement)
live in :mod:`merger.team.params`; they are re-exported here, where callers have always imported them.
Placing maps (:func:`~merger.team.frames.compose`, :class:`~merger.team.frames.Warps`,
:func:`~merger.team.frames.place_on_frame0`) is :mod:`merger.team.frames`.

For three maps the thesis evaluates three orders (3.10): a pair (1,2), (1,3) or (2,3) is aligned first,
then the third map is aligned onto the superposition of the pair. Here an *order* is a sequence of map
indices; its first two are the first pair and every further map is aligned onto the superposition of
all maps before it. :func:`merge_orders` gives one order per pair, so N maps give N(N−1)/2 orders (the
thesis's three for N = 3) and nothing below assumes N = 3. The maps are ranked by name, so every robot
of a team evaluates the same orders (and a simulation computes each once: :mod:`merger.team.memo`).

Every order is expressed in the frame of map 0 (the robot that merges) and verified on the whole maps:
ν_ij = ω̃(m*_i, m*_j) for every pair, accepted when all pass (:mod:`merger.team.verify`). Among accepted
orders the highest Σν wins (the thesis's rule). Beyond the thesis (``combine_orders``, on by default):
the accepted orders that place every map within 10° and 0.2 m of the winner are the same hypothesis
measured along different orders, and the chosen placement is their mean — verified again on the whole
maps like an order, else the winner's own placement stands (:func:`_combine`).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

from ..grid import OccupancyGrid
from ..search import Alignment, RotationProblem, angle_diff_deg, search, wrap_deg
from ..search.local import local_search
from ..transform import canvas, overlap, paste
from .ambiguity import PairAmbiguity, resolve
from .evidence import refine
from .frames import Warps, compose, merged_on_frame0, place_on_frame0, shifted
from .memo import Memo, map_key
from .params import ORIGIN, MapInput, MergeParams, OrderResult, Placement, TeamMergeResult
from .pool import parallel_map, start_clock
from .superpose import fuse_grids, superpose
from .verify import Verification, no_evidence, pairwise, refine_limit_m, refined_placement, verify

AMBIGUOUS_DEG = 10.0  # the ambiguity rule: another accepted order places a map more than this apart in angle
AMBIGUOUS_M = 0.2  # ... or more than this apart in translation


def merge_orders(n: int, names=None) -> list[tuple[int, ...]]:
    """One order per pair (a, b), a < b: the pair first, then the remaining maps by index. With ``names``
    (the maps' names by index) the maps are ranked by name instead of by index: every robot then
    evaluates the same orders (its own map is not always first), so a simulation's robots share their
    searches (:mod:`merger.team.memo`); each order is still expressed in the merging robot's frame."""
    if n < 2:
        raise ValueError(f"merging needs at least two maps, got {n}")
    rank = list(range(n)) if names is None else sorted(range(n), key=lambda k: names[k])
    return [(rank[a], rank[b], *[rank[k] for k in range(n) if k not in (a, b)]) for a, b in pairwise([None] * n)]


def pair_key(ref: MapInput, mov: MapInput, params: MergeParams):
    """What the search of ``mov`` onto ``ref`` depends on (None: the maps carry no version)."""
    if ref.version is None or mov.version is None:
        return None
    return (ref.name, ref.version, tuple(ref.center), mov.name, mov.version, tuple(mov.center),
            params.roi_m, params.measure, params.method, params.window_m, params.refine, params.margin,
            params.roi_min_support, params.teammate_radius_m, params.teammate_shift_m)


def problem_for(ref: OccupancyGrid, ref_center, mov: MapInput, params: MergeParams) -> RotationProblem:
    """The search problem of ``mov`` onto ``ref`` (a map or a superposition) with ``params``."""
    return RotationProblem(ref, mov.grid, tuple(ref_center), tuple(mov.center), params.roi_m, params.measure,
                           params.window_m, params.refine, params.roi_min_support)


def align_order(maps: list[MapInput], order: tuple[int, ...], params: MergeParams,
                reuse: dict | None = None, warps: Warps | None = None, memo: Memo | None = None,
                around: dict[int, Placement] | None = None):
    """Search the placements of one order; returns (θ, t) onto map 0 per map index, the search steps and
    the steps' ambiguities (:func:`merger.team.ambiguity.resolve`: a step whose runner-up scores within the
    margin is verified on the whole maps under both hypotheses, and takes the one that evidence separates).

    ``reuse``: alignments of raw map pairs by :func:`pair_key`; the order's first step is taken from it
    when its two maps are unchanged, and stored in it otherwise (searches are deterministic, so a reused
    alignment is the one the search would return). ``warps``: the cycle's shared :class:`Warps`.
    ``memo``: steps shared with other callers (:mod:`merger.team.memo`), keyed by the maps the step depends on:
    the ones placed before it (their placements follow from them) and the moving one.
    ``around``: per map index an earlier placement onto the order's first map (a tracked answer,
    :mod:`merger.team.track`): each step is then the exact local search about it (no runner-up, no reuse)."""
    warps = Warps(maps) if warps is None else warps
    first = maps[order[0]]
    sup = first.grid
    onto_first: dict[int, Placement] = {order[0]: (0.0, ORIGIN)}
    steps, ambiguous = [], []
    for k in order[1:]:
        m = maps[k]
        key = pair_key(first, m, params) if reuse is not None and k == order[1] and around is None else None
        hit = reuse.get(key) if key is not None else None
        if hit is None and around is not None:
            prob = problem_for(sup, first.center, m, params)
            th, t = around[k]
            cells = (int(round(t[0] / sup.resolution)), int(round(t[1] / sup.resolution)))
            placed = order[:order.index(k)]
            hit = (local_search(prob, th, cells), None) if memo is None else memo.get(
                ("order-step-local", tuple(map_key(maps[x]) for x in placed), map_key(m), params, th, cells),
                lambda prob=prob, th=th, cells=cells: (local_search(prob, th, cells), None))
        if hit is None:
            prob = problem_for(sup, first.center, m, params)
            placed = order[:order.index(k)]
            ref = "+".join(maps[x].name for x in placed)

            def step(prob=prob, ref=ref, sup=sup, k=k, m=m):
                return resolve(prob, search(prob, params.method), params.margin,
                               _step_check(sup, warps, order[0], k, params, f"{ref}|{m.name}"), ref, m.name)
            if memo is None:
                hit = step()
            else:
                hit = memo.get(("order-step", tuple(map_key(maps[x]) for x in placed), map_key(m), params), step)
            if key is not None:
                reuse[key] = hit
        al, amb = hit
        if amb is not None:
            ambiguous.append(amb)
        onto_first[k] = (al.theta_deg, al.translation_m)
        steps.append((m.name, al))
        if k != order[-1]:
            cv = canvas(sup, [warps.placed(k, *onto_first[k])], first.center)
            sup = OccupancyGrid(superpose(paste(sup, cv).states,
                                          paste(warps.get(order[0], k, *onto_first[k]), cv).states),
                                cv.resolution, cv.origin)
    return compose(onto_first, order[0], 0), tuple(steps), tuple(ambiguous)


def _step_check(onto: OccupancyGrid, warps: Warps, frame: int, k: int, params: MergeParams, label: str):
    """Whole-map verification of an alignment of map ``k`` onto ``onto`` (a map or a superposition on map
    ``frame``'s lattice, about its center): the ambiguity rule's evidence for one step of an order."""
    def check(al: Alignment) -> Verification:
        return verify(*overlap(onto, warps.get(frame, k, al.theta_deg, al.translation_m)),
                      nu_min=params.nu_min, min_support=params.min_support, label=label)
    return check


def order_result(maps: list[MapInput], order: tuple[int, ...], params: MergeParams, place0, steps,
                 warps: Warps, ambiguous: tuple[PairAmbiguity, ...] = ()) -> OrderResult:
    """An order's placements (``place0``: (θ, t) onto map 0 per index) verified on the whole maps: every pair
    of maps by the strategy's rule (the thesis's, ν ≥ ν_min with the minimum support), refused when one
    fails, a step had too little evidence, or an ambiguous pair of the order was left unresolved."""
    if params.verification_rule.whole_maps:
        checks = {f"{maps[i].name}|{maps[j].name}": warps.check(i, place0[i], j, place0[j], params)
                  for i, j in pairwise(maps)}
    else:
        checks = {}
        for name, al in steps:
            ok = al.score >= params.score_min
            checks[name] = Verification(al.score, al.counts, ok, "" if ok else
                                        f"score of {name} = {al.score:.3f} < score_min {params.score_min:g}")
    failed = [no_evidence(al, params.roi_min_support, name) for name, al in steps if not al.has_evidence]
    failed += [c.reason for c in checks.values() if not c.passed] + [a.reason for a in ambiguous if not a.used]
    return OrderResult(tuple(maps[k].name for k in order), {maps[k].name: place0[k][0] for k in order},
                       steps, checks, not failed, "; ".join(failed),
                       {maps[k].name: place0[k][1] for k in order})


def beyond_refusal(order: OrderResult, settled=None) -> str:
    """Why the chosen order is refused because a search of it found a better alignment outside the
    translation window ("" if none did; see :func:`merger.search.beyond_window`). The steps' guards are
    computed side by side (merger.team.pool; each is a pure function of its search, the same on any schedule).
    ``settled(name, alignment)`` (optional, :func:`whole_map_guard`): true when the whole maps answer a
    step's guard — its alignment beyond the window fits the whole maps no better than the one inside."""
    parallel_map(lambda step: step[1].beyond, [s for s in order.steps if s[1].window_m > 0])
    for name, al in order.steps:
        if al.window_m > 0 and al.beyond is not None and not (settled is not None and settled(name, al)):
            th, t, v = al.beyond
            return (f"beyond the window: {name}'s best alignment lies outside ±{al.window_m:g} m (θ {th:.0f}°, "
                    f"t ({t[0]:+.2f}, {t[1]:+.2f}) m, coarse score {v:.3f}; inside the window: θ "
                    f"{al.theta_deg:.1f}°, score {al.score:.3f}): the center error may exceed half the window, "
                    f"or the ROI holds too little of the maps; widen the window (merger.window_m, merger "
                    f"--window) or the ROI (merger.roi_m, --roi)")
    return ""


def merge_team(maps: list[MapInput], params: MergeParams = MergeParams(), *,  # noqa: B008 (frozen)
               reuse: dict | None = None, memo: Memo | None = None,
               orders: list[tuple[int, ...]] | None = None) -> TeamMergeResult:
    """Merge N ≥ 2 maps in every order, verify, and choose (thesis 3.3.1).

    Results are in the frame of ``maps[0]``; ``merged`` is the fused map of the chosen order.
    ``reuse`` (a dict kept by the caller between cycles, e.g. :class:`merger.team.online.TeamMerger`): pair
    alignments of maps that carry a ``version`` are reused while both maps are unchanged; after the
    cycle it holds only this cycle's pairs. The result is the same as without it. ``memo``
    (:mod:`merger.team.memo`): search steps shared with the other robots of a simulation; the result is the
    same, its ``charged_ms`` the computing time of the steps taken from the memo. ``orders``: the orders to
    evaluate (default :func:`merge_orders`; ``merger align`` gives ``[(0, 1)]``: MOVING searched onto REF,
    with every check of a merge).
    """
    t0, clock = time.perf_counter(), start_clock()
    if memo is not None:
        memo.take_charged_ms()
    orders = merge_orders(len(maps), [m.name for m in maps]) if orders is None else [tuple(o) for o in orders]
    warps = Warps(maps)
    # the orders are independent: searched side by side (merger.team.pool; the same result on any schedule)
    aligned = parallel_map(lambda o: align_order(maps, o, params, reuse, warps, memo), orders)
    if reuse is not None:  # keep only this cycle's pairs
        live = {pair_key(maps[o[0]], maps[o[1]], params) for o in orders}
        for key in [k for k in reuse if k not in live]:
            del reuse[key]
    results = [order_result(maps, o, params, place0, steps, warps, amb)
               for o, (place0, steps, amb) in zip(orders, aligned, strict=True)]
    accepted = [k for k, r in enumerate(results) if r.accepted]
    chosen, merged, layers, ambiguity = None, None, {}, ""
    if accepted:
        best = max(accepted, key=lambda k: results[k].nu_sum)  # the first of equal sums
        ambiguity = _ambiguity(results, accepted, best, params.margin) or \
            beyond_refusal(results[best], whole_map_guard(maps, orders[best], params, warps))
        chosen = None if ambiguity else results[best]
    place = aligned[best][0] if chosen is not None else None
    if chosen is not None and params.combine_orders and params.verification_rule.whole_maps:
        combined = _combine(maps, results, [a[0] for a in aligned], accepted, best, orders[best], params, warps)
        if combined is not None:
            results[best], place = combined
            chosen = results[best]
    if chosen is not None:
        chosen, place = refine_chosen(maps, place, warps, params, chosen)
        results[best] = chosen
        merged, layers = merged_on_frame0(maps, place, warps)
    return TeamMergeResult(maps[0].name, tuple(results), chosen, merged, layers,
                           (time.perf_counter() - t0) * 1e3, ambiguity, tuple(a for _, _, amb in aligned for a in amb),
                           memo.take_charged_ms() if memo is not None else 0.0, cpu_ms=clock.ms())


def whole_map_guard(maps: list[MapInput], order: tuple[int, ...], params: MergeParams, warps: Warps):
    """With the contrast evidence (a verification rule that runs it: "auto", "contrast"), the guard beyond the window of an
    order's first step (a pair of raw maps) is settled on the whole maps: the alignment beyond the window and
    the one inside are each refined on the whole maps (:func:`merger.team.evidence.refine`, ±1 m), and the
    guard stands only when the one beyond fits better. On bent real maps the ROI's optimum lies a little
    beyond a 0.5 m window (0.6–1.15 m) while the whole maps fit best inside it (Halmstad: 11 of 108
    correct answers refused, docs/merging-real-maps.md). None for the thesis's rule (the guard as it is)."""
    if not params.verification_rule.contrast:
        return None
    i, j = order[0], order[1]

    def fit(al_theta: float, t) -> float:
        t = (float(t[0]), float(t[1]))
        return refine(maps[i].grid, warps.get(i, j, al_theta, t), shifted(maps[i].center, t), params.tolerance_m,
                      refine_limit_m(params))[0]

    def settled(name: str, al: Alignment) -> bool:
        if name != maps[j].name or al.beyond is None:  # a later step: onto a superposition
            return False
        th, t, _ = al.beyond
        return fit(al.theta_deg, al.translation_m) >= fit(th, t)
    return settled


def refine_chosen(maps: list[MapInput], place: dict[int, Placement], warps: Warps, params: MergeParams,
                  chosen: OrderResult, keep: frozenset[int] = frozenset()) -> tuple[OrderResult, dict[int, Placement]]:
    """The accepted placements refined on the whole maps (``params.refine_whole``; otherwise unchanged).

    ``place``: (θ, t) onto map 0 per index of ``maps``. A placed map k ≥ 1 that some check of ``chosen``
    passed by the contrast rule (maps that agree only within a few cells) is fitted onto the fusion of the
    other maps at their accepted placements (one pass, each against the same unrefined others:
    :func:`merger.team.verify.refined_placement`, the contrast rule's fit within ±5°, ±1 m). A map whose
    checks the thesis's ν passed keeps the search's placement: its maps agree cell by cell, and the search's
    cell-exact optimum is finer than the tolerant fit (on the simulator's maps the fit moved a placement
    14 cm, beyond the bench's 10 cm). The result carries the refined placement and the search's beside it
    (``search_theta_deg``, ``search_translation_m``); its checks stay those of the search's placement.
    ``keep``: indices of maps whose placement cell-exact evidence holds whatever the checks (the tree: a map
    with a consistent pair the thesis's ν passed): kept as well."""
    if not params.refine_whole or not params.verification_rule.whole_maps or len(place) < 2:
        return chosen, place
    names = {k: maps[k].name for k in place}
    todo = [k for k in place if k != 0 and k not in keep and any(v.contrast is not None and v.passed for pair, v in chosen.checks.items()
                                               if names[k] in pair.split("|"))]
    if not todo:
        return chosen, place
    lay = place_on_frame0(maps, place, warps)
    out = dict(place)
    for k in todo:
        others = fuse_grids([g for j, g in enumerate(lay) if j != k])
        th, t = refined_placement(others, lay[k], shifted(maps[0].center, place[k][1]), *place[k], params)
        out[k] = (wrap_deg(th), t)
    return replace(chosen, theta_deg={names[k]: out[k][0] for k in place},
                   translation_m={names[k]: out[k][1] for k in place},
                   search_theta_deg={names[k]: place[k][0] for k in place},
                   search_translation_m={names[k]: tuple(place[k][1]) for k in place}), out


def _combine(maps: list[MapInput], results: list[OrderResult], places: list[dict[int, Placement]],
             accepted: list[int], best: int, order: tuple[int, ...], params: MergeParams, warps: Warps):
    """The mean placement of the accepted orders that agree with the best one, verified; ``None`` when
    fewer than two agree or the mean does not pass.

    Agree: every map within AMBIGUOUS_DEG and AMBIGUOUS_M of the best's placement (the ambiguity rule's
    distances: closer than that, two orders are one hypothesis, not rivals). The mean is taken per map
    over those orders, angles as the best's angle plus the mean wrapped difference, translations
    arithmetically; it replaces the best order's result (same order and steps, ``combined`` naming the
    orders averaged, its pairs verified again on the whole maps). Each order aligns the maps along a
    different sequence of searches, so their small errors differ; on scene2-thesis (seed 5, 17.7 s) the
    two accepted orders had Σν 2.9022 (errors 0.05°/0.21°) and 2.9023 (2.05°/1.34°: a sparse map rotated
    2° loses a few overlapping cells and its ν rises on fewer cells), the thesis's rule took the second."""
    b = results[best]
    agree = [k for k in accepted
             if all(abs(angle_diff_deg(results[k].theta_deg[n], b.theta_deg[n])) <= AMBIGUOUS_DEG
                    and math.dist(results[k].translation(n), b.translation(n)) <= AMBIGUOUS_M for n in b.theta_deg)]
    if len(agree) < 2:
        return None
    place: dict[int, Placement] = {}
    for i in range(len(maps)):
        th0 = places[best][i][0]
        dth = sum(angle_diff_deg(places[k][i][0], th0) for k in agree) / len(agree)
        tx = sum(places[k][i][1][0] for k in agree) / len(agree)
        ty = sum(places[k][i][1][1] for k in agree) / len(agree)
        place[i] = (0.0, ORIGIN) if i == 0 else (wrap_deg(th0 + dth), (float(tx), float(ty)))
    fused = order_result(maps, order, params, place, b.steps, warps)
    if not fused.accepted:
        return None
    return replace(fused, combined=tuple(results[k].order for k in agree)), place


def _ambiguity(results: list[OrderResult], accepted: list[int], best: int, margin: float) -> str:
    """Why the best accepted order is ambiguous ("" if it is not): another accepted order places some map
    more than AMBIGUOUS_DEG or AMBIGUOUS_M away, and the best's mean ν beats it by less than ``margin``."""
    if margin <= 0:
        return ""
    b = results[best]
    npairs = max(len(b.checks), 1)
    for k in accepted:
        o = results[k]
        if k == best:
            continue
        for name in b.theta_deg:
            dth = abs(angle_diff_deg(o.theta_deg[name], b.theta_deg[name]))
            dt = math.dist(o.translation(name), b.translation(name))
            if dth > AMBIGUOUS_DEG or dt > AMBIGUOUS_M:
                gap = (b.nu_sum - o.nu_sum) / npairs
                if gap < margin:
                    return (f"ambiguous: order {'→'.join(o.order)} also passes and places {name} "
                            f"{dth:.1f}° / {dt:.2f} m away; mean ν {b.nu_sum / npairs:.3f} vs "
                            f"{o.nu_sum / npairs:.3f} (margin {margin:g})")
                break
    return ""
