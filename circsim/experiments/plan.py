"""A sweep's plan: the grid's axes and one :class:`RunTask` per (combination, seed), validated first.

The contract: :func:`parse_grid` reads ``--grid key=v1,v2,...`` (values parsed as YAML, keys and
aliases resolved); :func:`plan` expands every combination × every seed (seed = base seed + i) and builds
and validates each one's scenario before anything runs, so a bad key or value is one
:class:`SweepError` line naming it. A :class:`RunTask` is plain, picklable data (the base scenario as a
dict, the grid values, the seed and its :func:`run_key`), run by :func:`circsim.experiments.sweep.run_one`.
The file names of a sweep's folder are here too (:data:`RUNS_JSONL` ...). See docs/sweeps.md.
"""

from __future__ import annotations

import hashlib
import itertools
import json
from collections.abc import Iterable
from dataclasses import dataclass

from merger.limits import load_yaml

from ..config.scenario import ALIASES, Scenario, ScenarioError, scenario_from_dict

RUNS_JSONL, RUNS_CSV, RUNS_PARQUET, SUMMARY_CSV = "runs.jsonl", "runs.csv", "runs.parquet", "summary.csv"
ERRORS_JSONL = "errors.jsonl"



class SweepError(ValueError):
    """A user error in a sweep's grid or output directory (one line)."""


@dataclass(frozen=True)
class Axis:
    key: str  # canonical scenario key path
    values: tuple
    texts: tuple = ()  # the values as the user wrote them (for messages)


@dataclass(frozen=True)
class RunTask:
    """Everything a worker needs to run one (combination, seed): plain data, picklable."""

    raw: dict  # the base scenario as data (with --set applied)
    source: str
    grid: tuple[tuple[str, object], ...]  # (key, value) per axis
    seed: int
    key: str

    def assignments(self) -> list[str]:
        return [f"{k}={value_text(v)}" for k, v in self.grid] + [f"seed={self.seed}"]

    def scenario(self) -> Scenario:
        return scenario_from_dict(self.raw, source=self.source).with_overrides(self.assignments())


def _norm(v):
    """Numbers as floats so that 0 and 0.0 are the same grid value (and the same run key)."""
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else v


def value_text(v) -> str:
    """A grid value as ``--set`` text: a whole number as an integer (``3``, not ``3.0``), so that integer
    keys (``world.generate.seed``, ``world.generate.rooms``) can be swept; a number key reads 3 as 3.0."""
    if isinstance(v, float) and v.is_integer() and abs(v) < 2 ** 53:
        return str(int(v))
    return json.dumps(v)


def parse_grid(specs: Iterable[str]) -> list[Axis]:
    """``["center_error=0,0.1", "network.latency_s=0,1"]`` → axes (key aliases resolved)."""
    import yaml

    axes: list[Axis] = []
    for spec in specs:
        key, sep, text = spec.partition("=")
        key = key.strip()
        if not sep or not key or not text.strip():
            raise SweepError(f"--grid {spec!r}: expected KEY.PATH=V1,V2,... (e.g. center_error=0,0.1,0.2)")
        key = ALIASES.get(key, key)
        if key == "seed":
            raise SweepError(f"--grid {spec!r}: seeds are not a grid axis; use --seed BASE and --seeds N")
        values, texts = [], []
        for item in text.split(","):
            texts.append(item.strip())
            try:
                v = load_yaml(item)  # as --set parses values (YAML 1.2 numbers: 1e-1 is a number)
            except (yaml.YAMLError, ValueError, TypeError, RecursionError):
                raise SweepError(f"--grid {key}: value {item!r} is not valid YAML") from None
            if v is None:
                raise SweepError(f"--grid {key}: empty value in {text!r}; expected V1,V2,...")
            values.append(_norm(v))
        if len(set(map(json.dumps, values))) != len(values):
            raise SweepError(f"--grid {key}: repeated value in {text!r}")
        if any(a.key == key for a in axes):
            raise SweepError(f"--grid {key}: given twice; put all its values in one --grid")
        axes.append(Axis(key, tuple(values), tuple(texts)))
    return axes


def _check(base: Scenario, combo, label: str) -> None:
    try:
        base.with_overrides([f"{k}={value_text(v)}" for k, v in combo])
    except ScenarioError as e:
        msg = str(e).split("): ", 1)[-1]  # "<file> (--set k=v): path: expectation" → "path: expectation"
        raise SweepError(f"{base.source}: {label}: {msg}") from None


def base_digest(raw: dict) -> str:
    """A short digest of the base scenario (after ``--set``), its seed left out (runs carry their own)."""
    data = {k: v for k, v in raw.items() if k != "seed"}
    return hashlib.sha1(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()[:12]


def run_key(scenario: str, grid, seed: int, base: str = "") -> str:
    """What identifies a run for ``--resume``: scenario name, base scenario digest (so a changed ``--set``
    or scenario file is not mistaken for a finished run), grid values and seed."""
    return json.dumps({"scenario": scenario, "base": base, "grid": {k: _norm(v) for k, v in grid},
                       "seed": int(seed)}, sort_keys=True)


def plan(base: Scenario, axes: list[Axis], seeds: int) -> list[RunTask]:
    """Every (combination, seed) as a task; builds every combination's scenario first (validation)."""
    if seeds < 1:
        raise SweepError(f"--seeds: expected an integer >= 1, got {seeds}")
    for a in axes:  # one key at a time first: the message names the culprit key and value
        for v, text in zip(a.values, a.texts, strict=True):
            _check(base, [(a.key, v)], f"--grid {a.key}={text}")
    combos = list(itertools.product(*[[(a.key, v) for v in a.values] for a in axes]))
    for combo in combos:  # then every combination (keys that constrain each other)
        _check(base, combo, "--grid " + " ".join(f"{k}={json.dumps(v)}" for k, v in combo))
    base_seed, digest = int(base.seed), base_digest(base.raw)
    return [RunTask(base.raw, base.source, combo, base_seed + i,
                    run_key(base.name, combo, base_seed + i, digest))
            for combo in combos for i in range(seeds)]
