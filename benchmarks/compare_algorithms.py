"""The merging methods on the same truth, in one command (issue 35): thesis, features (m-explore map_merge's
pipeline) and hough (Carpin's Hough spectrum), on simulated scenes and on real maps.

    python benchmarks/compare_algorithms.py --out runs/compare [--scenes scene1,scene2,hall4]
        [--errors 0,0.1,0.25] [--seeds 2] [--duration 30] [--data ../shared/data/real-maps]

1. per scene, ``circsim sweep SCENE --grid merger.algorithm=thesis,features,hough --grid center_error=...``
   (``merger.window_m`` 0.5 for every run: the thesis's window covers the errors; the others ignore it),
   into OUT/<scene>/ (resumable: ``--resume``);
2. real maps from independent runs (:mod:`tests.realdata`: the Halmstad pairs at ROI 16 m with centers
   exact and 0.5 m off, the A.P. Hill pairs, the UC Merced runs, the demo pair; correct = θ within 3° and
   the true center placed within 0.5 m plus the truth's RMS) and three robots' views of the TurtleBot3
   office map (``merger demo --real``, seeds 1–5, centers 0.3 m off; exact truth; correct = every map
   within 2° and 0.1 m), each merged by every method (:func:`merger.algorithms.merge_every_map`);
3. OUT/compare.md (both tables), OUT/compare.json, OUT/compare.png (:mod:`circsim.experiments.compare`).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from circsim.config.scenario import bundled_scenarios, load_scenario  # noqa: E402
from circsim.experiments import compare  # noqa: E402
from merger.algorithms import ALGORITHMS, merge_every_map  # noqa: E402
from merger.io.mapio import load_map  # noqa: E402
from merger.search import angle_diff_deg  # noqa: E402
from merger.team.orders import MapInput, MergeParams  # noqa: E402
from tests.paths import REAL_MAP  # noqa: E402
from tests.realdata import DATA, aphill_cases, correct, demo_cases, grid, halmstad_cases, ucmerced_cases  # noqa: E402

VENV_CIRCSIM = Path(sys.executable).with_name("circsim")


def run_sweeps(out: Path, scenes, errors, seeds: int, duration: float) -> list[dict]:
    rows = []
    for scene in scenes:
        d = out / scene
        cmd = [str(VENV_CIRCSIM), "sweep", scene, "--grid", f"merger.algorithm={','.join(ALGORITHMS)}",
               "--grid", "center_error=" + ",".join(f"{e:g}" for e in errors), "--seeds", str(seeds),
               "--set", f"duration_s={duration:g}", "--set", "merger.window_m=0.5", "--workers", "1",
               "--out", str(d), "--no-plots", "--quiet"]
        if (d / "runs.jsonl").exists():
            cmd.append("--resume")
        print(" ".join(cmd), flush=True)
        subprocess.run(cmd, check=True)
        rows += [json.loads(line) for line in (d / "runs.jsonl").read_text().splitlines() if line.strip()]
    return rows


def _verdict(set_name: str, alg: str, maps, params, judge) -> dict:
    t0 = time.perf_counter()
    res = merge_every_map(alg, maps, params)
    ms = (time.perf_counter() - t0) * 1e3
    return {"set": set_name, "algorithm": alg, "accepted": res.accepted, "correct": judge(res.top), "ms": ms,
            "reason": res.reason[:200]}


def real_pairs(data: Path) -> list[dict]:
    sets = [("Halmstad, exact centers", halmstad_cases(data, [16.0], [0.0])),
            ("Halmstad, centers 0.5 m off", halmstad_cases(data, [16.0], [0.5])),
            ("A.P. Hill", aphill_cases(data, [16.0], [0.0])),
            ("UC Merced", ucmerced_cases(data, [16.0], [0.0])),
            ("demo pair", demo_cases(data, [16.0], [0.0]))]
    out = []
    for name, cases in sets:
        for c in cases:
            maps = [MapInput("a_ref", grid(c.ref), c.c_ref), MapInput("b_mov", grid(c.mov), c.c_mov)]
            params = replace(MergeParams(), roi_m=c.roi_m, window_m=c.window_m)
            for alg in ALGORITHMS:
                def judge(top, c=c):
                    return "b_mov" in top.theta_deg and bool(correct(c, top.theta_deg["b_mov"], top.translation("b_mov")))
                out.append(_verdict(name, alg, maps, params, judge))
        print(f"{name}: {len(cases)} pairs", flush=True)
    return out


def office_views(seeds=range(1, 6), error=0.3) -> list[dict]:
    from merger.cli import main as merger_main
    from merger.limits import load_yaml

    out = []
    for seed in seeds:
        with tempfile.TemporaryDirectory() as d:
            with contextlib.redirect_stdout(io.StringIO()):
                merger_main(["demo", "--real", str(REAL_MAP), "--center-error", f"{error:g}", "--seed", str(seed),
                             "-o", d, "--json"])
            meta = load_yaml((Path(d) / "centers.yaml").read_text())
            maps = [MapInput(n, load_map(str(Path(d) / m["map"])), tuple(m["center"])) for n, m in meta["maps"].items()]
            truth = meta["truth"]

            def judge(top, maps=maps, truth=truth):
                if len(top.theta_deg) != len(maps):
                    return False
                for k, tr in truth.items():
                    t, tt = top.translation(k), tr["translation_m"]
                    if abs(angle_diff_deg(top.theta_deg[k], tr["theta_deg"])) > 2.0 + 1e-9 or \
                            ((t[0] - tt[0]) ** 2 + (t[1] - tt[1]) ** 2) ** 0.5 > 0.1 + 1e-9:
                        return False
                return True
            for alg in ALGORITHMS:
                out.append(_verdict("TurtleBot3 office views", alg, maps, MergeParams(), judge))
    print(f"TurtleBot3 office views: {len(list(seeds))} teams", flush=True)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--scenes", default="scene1,scene2,hall4")
    ap.add_argument("--errors", default="0,0.1,0.25")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--data", type=Path, default=DATA)
    ap.add_argument("--no-real", action="store_true", help="only the simulated scenes")
    a = ap.parse_args(argv)
    scenes = a.scenes.split(",")
    errors = [float(v) for v in a.errors.split(",")]
    rows = run_sweeps(a.out, scenes, errors, a.seeds, a.duration)
    team = {s: len(load_scenario(bundled_scenarios()[s]).robots.names) for s in scenes}
    sim = compare.sim_summary(rows, team)
    verdicts = [] if a.no_real else real_pairs(a.data) + office_views()
    real = compare.real_summary(verdicts)
    algs = list(ALGORITHMS)
    text = ("## Simulated scenes: robots merged / first correct merge / false merges per run (merge cycle median)\n\n"
            + compare.sim_table(sim, algs) + "\n\n## Real maps: correct / false / refused pairs (median time per pair)\n\n"
            + compare.real_table(real, algs) + "\n")
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "compare.md").write_text(text)
    (a.out / "compare.json").write_text(json.dumps({"sim": sim, "real": real, "verdicts": verdicts}, indent=1))
    compare.plot(sim, real, algs, a.out / "compare.png")
    print(text)
    print(f"written: {a.out / 'compare.md'}, {a.out / 'compare.json'}, {a.out / 'compare.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
