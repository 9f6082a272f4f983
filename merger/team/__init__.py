"""Merging a team's maps: from pairwise searches to one accepted placement of every map.

* :mod:`.orders` — the thesis's procedure: every merge order, each verified, the best accepted one chosen
  (``merge_team``, ``MergeParams``, ``TeamMergeResult``);
* :mod:`.tree` — the alternative for large teams: verified pairs along a maximum spanning tree (the
  graph's arithmetic: :mod:`.posegraph`);
* :mod:`.frames` (placements between frames, maps placed on a frame), :mod:`.verify` (ν on the whole
  maps), :mod:`.evidence` (the contrast rule for real maps), :mod:`.ambiguity` (a runner-up within the
  margin is weighed on the whole maps), :mod:`.superpose` (the merged map);
* :mod:`.params` (``MergeParams`` and the value types) over :mod:`.defaults` (the settings' defaults and the
  tables of the named ones: verification rules, research modes), the bottom of the package's layers
  (docs/design/layout.md);
* :mod:`.online` (``TeamMerger``: maps arriving over time, the strategies' table), :mod:`.shared` (hypotheses shared between
  robots), :mod:`.memo` (searches shared by content key), :mod:`.pool` (a cycle's searches on threads).

Every module here searches through :mod:`merger.search` and never imports :mod:`merger.io`;
docs/merging-algorithm.md explains the rules and their measured effect.
"""
