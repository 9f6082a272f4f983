"""A robot's online merger for a pairwise algorithm (``features``, ``hough``): :class:`merger.team.online.
TeamMerger` — the same maps held, the same readiness and hypotheses — whose merge cycle is
:func:`merger.algorithms.merge`, each pair's answer kept per map version (the algorithms are deterministic).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..team.online import TeamMerger
from ..team.orders import TeamMergeResult
from . import ALGORITHMS_BY_NAME, merge

PAIRWISE = tuple(n for n, a in ALGORITHMS_BY_NAME.items() if a.pairwise)  # the algorithms an AlgorithmMerger runs


@dataclass
class AlgorithmMerger(TeamMerger):
    algorithm: str = "features"
    _answers: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.algorithm not in PAIRWISE:
            raise ValueError(f"AlgorithmMerger: algorithm must be one of {', '.join(PAIRWISE)}, "
                             f"got {self.algorithm!r} (thesis: TeamMerger)")

    def cycle(self, now: float | None = None) -> TeamMergeResult:
        if not self.ready():
            raise RuntimeError(f"{self.self_name}: not enough maps to merge ({sorted(self.maps)})")
        inputs = self.inputs()
        live = {(m.name, m.version) for m in inputs}
        self._answers = {k: v for k, v in self._answers.items() if (k[1], k[2]) in live and (k[3], k[4]) in live}
        result = merge(self.algorithm, inputs, self.params, cache=self._answers)
        self.cycles += 1
        if result.accepted:
            self.current = result
            self.current_stamp = now
        return result


def make_merger(algorithm: str, *args, **kwargs) -> TeamMerger:
    """The online merger of ``algorithm``: :class:`TeamMerger` for ``thesis`` (a method that merges a team
    itself), else :class:`AlgorithmMerger`."""
    if algorithm in ALGORITHMS_BY_NAME and not ALGORITHMS_BY_NAME[algorithm].pairwise:
        return TeamMerger(*args, **kwargs)
    return AlgorithmMerger(*args, algorithm=algorithm, **kwargs)
