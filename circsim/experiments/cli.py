"""Registry of the experiment subcommands (``circsim offline``, ``circsim sweep``).

Each entry is a function ``register(subparsers)`` that adds one subparser and sets its handler with
``parser.set_defaults(func=handler)``; the handler takes the parsed args and returns an exit code.
A user error raises ``ValueError`` (or a subclass) with a one-line message: ``circsim.cli.main``
prints it and exits with 2 (:mod:`circsim.commands`: what the commands share).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from merger.io.mapio import ensure_output_dir, write_files

from ..record import jsonout


def _scenario_args(p) -> None:
    p.add_argument("--seed", type=int, help="base seed (default: the scenario's); seed i is base + i")
    p.add_argument("--set", action="append", default=[], metavar="KEY.PATH=VALUE",
                   help="override a scenario value for every run (repeatable)")
    p.add_argument("--quiet", action="store_true",
                   help="no progress on stderr (by default a bar on a terminal, else a line every 5 s of work)")


# --- circsim offline ---------------------------------------------------------------------------------
def register_offline(sub) -> None:
    from .offline import NCC_SCORE_MIN, OTHERS

    p = sub.add_parser("offline", help="the thesis's offline displacement experiment (figures 3.14/3.15)",
                       description="Robots displaced to ±φ around their start points (1° steps); the maps at "
                                   "every φ are merged offline with each method; prints the smallest φ of a "
                                   "first valid and correct merge beside the thesis's figures.")
    p.add_argument("scenarios", nargs="+", metavar="SCENARIO", help="scenario file(s) or bundled name(s)")
    p.add_argument("--methods", default="ncc,similarity", help="comma-separated: ncc, similarity")
    p.add_argument("--seeds", type=int, default=1, help="number of seeds per scenario (default 1)")
    p.add_argument("--max-deg", type=float, help="largest displacement φ (default: robots.offline.max_deg)")
    p.add_argument("--step-deg", type=float, help="displacement step (default: robots.offline.step_deg)")
    p.add_argument("--out", type=Path, help="write offline.csv, offline.json, records and first-merge overlays")
    p.add_argument("--full", action="store_true", help="merge at every φ up to max-deg (do not stop a "
                                                        "method at its first valid correct merge)")
    p.add_argument("--score-min", type=float, default=NCC_SCORE_MIN,
                   help=f"NCC acceptance threshold on every alignment's coefficient (default {NCC_SCORE_MIN})")
    p.add_argument("--others", choices=OTHERS, default="lockstep",
                   help="the other robots while one scans: displaced together (default), at start, absent")
    p.add_argument("--drift", choices=("arc", "path"), default="arc",
                   help="SLAM drift along the arc (re-localizing, default) or along the whole back-and-forth path")
    p.add_argument("--scans-per-pose", type=int, default=5, help="laser scans integrated at each pose")
    p.add_argument("--search-method", help="rotation search (default: fast if available, else reference)")
    p.add_argument("--save-maps", action="store_true", help="also save every robot's map at every φ as ROS "
                                                             "map files under OUT/maps/")
    p.add_argument("--calibrate", action="store_true",
                   help="instead: measure the NCC scores of wrong hypotheses over every φ and propose "
                        "--score-min (use seeds that the reported experiment does not use)")
    _scenario_args(p)
    p.set_defaults(func=cmd_offline)


def cmd_offline(args) -> int:
    from ..commands import begin_work, load_with_overrides
    from .offline import OfflineSettings

    methods = tuple(m.strip() for m in args.methods.split(",") if m.strip())
    if args.seeds < 1:
        raise ValueError(f"--seeds: expected an integer >= 1, got {args.seeds}")
    check_offline_args(args)
    settings = OfflineSettings(methods=methods, max_deg=args.max_deg, step_deg=args.step_deg,
                               scans_per_pose=args.scans_per_pose, others=args.others, drift=args.drift,
                               ncc_score_min=args.score_min, search_method=args.search_method, full=args.full)
    bases = [load_with_overrides(s, args.seed, args.set) for s in args.scenarios]
    scenarios = [b.with_overrides([f"seed={int(b.seed) + i}"]) for b in bases for i in range(args.seeds)]
    if args.out:
        ensure_output_dir(args.out, "--out")
        from merger.io.mapio import check_outputs

        check_outputs({args.out / n: "--out" for n in ("offline.csv", "offline_seeds.csv", "offline.json",
                                                       "offline_records.jsonl", "ncc_calibration.json")})
    begin_work()
    if args.calibrate:
        return _calibrate(scenarios, settings, args)
    return _offline(scenarios, settings, args)


def check_offline_args(args) -> None:
    """One-line errors for the numbers of ``circsim offline`` (NaN and infinities included)."""
    import math

    def finite(v):
        return v is not None and math.isfinite(v)

    if args.max_deg is not None and not (finite(args.max_deg) and 0 < args.max_deg <= 180):
        raise ValueError(f"--max-deg: expected a number of degrees in (0, 180], got {args.max_deg:g}")
    if args.step_deg is not None and not (finite(args.step_deg) and 0 < args.step_deg <= 180):
        raise ValueError(f"--step-deg: expected a number of degrees in (0, 180], got {args.step_deg:g}")
    if args.max_deg is not None and args.step_deg is not None and args.step_deg > args.max_deg:
        raise ValueError(f"--step-deg: expected at most --max-deg ({args.max_deg:g}), got {args.step_deg:g}")
    if not (finite(args.score_min) and -1 <= args.score_min <= 1):
        raise ValueError(f"--score-min: expected an NCC coefficient in [-1, 1], got {args.score_min:g}")
    if args.scans_per_pose < 1:
        raise ValueError(f"--scans-per-pose: expected an integer >= 1, got {args.scans_per_pose}")


def _offline(scenarios, settings, args) -> int:
    from merger.io.mapio import save_map

    from ..commands import interrupted_code
    from ..progress import progress_bar
    from .offline import default_search_method, format_table, run_offline, summarize

    search = settings.search_method or default_search_method()
    out: Path | None = args.out
    seed_results, records_path = [], (out / "offline_records.jsonl") if out else None
    rec_file = open(records_path, "w") if records_path else None
    bar = progress_bar(len(scenarios), "scene·seed", "offline", quiet=args.quiet)
    interrupted = False
    try:
        for sc in scenarios:
            def on_record(rec, sc=sc):
                bar.set_postfix_str(f"{sc.name} seed {sc.seed} {rec.method} φ={rec.phi_deg:g}")
                if rec_file:
                    rec_file.write(jsonout.dumps(rec.to_dict()) + "\n")
                    rec_file.flush()

            def on_maps(phi, grids, sc=sc):
                if out and args.save_maps:
                    for name, g in grids.items():
                        save_map(g, out / "maps" / sc.name / f"seed{sc.seed}" / f"phi{phi:g}" / f"{name}.yaml")

            results, _ = run_offline(sc, settings, on_record=on_record, on_maps=on_maps)
            for r in results.values():
                seed_results.append(r)
                if out and r.first_merge is not None:
                    save_first_merge(r, out / f"first_valid_{r.scene}_{r.method}_seed{r.seed}.png")
            bar.update(1)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        bar.close()
        if rec_file:
            rec_file.close()
    rows = summarize(seed_results)
    print(f"offline displacement experiment: smallest ±φ with a first valid and correct merge "
          f"(search {search}, NCC score_min {settings.ncc_score_min:g}, others {settings.others}, drift {settings.drift}, "
          f"{settings.scans_per_pose} scans/pose{', full range' if settings.full else ''})")
    print(format_table(rows))
    if out:
        _write_offline(out, rows, seed_results, settings, search, args)
        print(f"written: {out / 'offline.csv'}, {out / 'offline_seeds.csv'}, {out / 'offline.json'}, "
              f"{records_path}")
    if interrupted:
        print("circsim: interrupted; the table holds the scenes and seeds that finished", file=sys.stderr)
        return interrupted_code()
    return 0


def save_first_merge(r, path: Path, *, cell_px: int = 2) -> Path:
    """The thesis-style overlay (fig. 3.15 colours) of a first valid merge: cropped to the known cells,
    with its scene, method and ±φ in the title, a legend of robot colours and a 1 m scale bar."""
    import cv2

    from merger.io.overlay import overlay_picture

    fm = r.first_merge
    names = list(fm.layers)
    title = f"{r.scene} {r.method} +-{r.first_correct_phi_deg:g} deg (seed {r.seed})"
    rgb = overlay_picture([fm.layers[n].states for n in names], names, fm.layers[names[0]].resolution,
                          title=title, cell_px=cell_px)
    ok, png = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if ok:
        write_files({path: png.tobytes()})
    return path


def _write_offline(out: Path, rows, seed_results, settings, search, args) -> None:
    from dataclasses import asdict

    from .tables import write_csv

    write_csv(rows, out / "offline.csv")
    write_csv([r.to_dict() for r in seed_results], out / "offline_seeds.csv")
    meta = {"command": "circsim " + " ".join(sys.argv[1:]) if sys.argv else "", "settings": asdict(settings),
            "search_method": search, "scenarios": args.scenarios, "seeds": args.seeds, "set": args.set}
    write_files({out / "offline.json": jsonout.dumps(
        {"meta": meta, "summary": rows, "per_seed": [r.to_dict() for r in seed_results]}, indent=2).encode()})


def _calibrate(scenarios, settings, args) -> int:
    from ..progress import progress_bar
    from .offline import calibrated_threshold, ncc_calibration_rows

    rows = []
    with progress_bar(len(scenarios), "scene·seed", "calibrate", quiet=args.quiet) as bar:
        for sc in scenarios:
            rows += ncc_calibration_rows(sc, settings)
            bar.update(1)
    cal = calibrated_threshold(rows)
    print(f"NCC calibration over {len(scenarios)} scene·seeds, {cal['alignments']} alignments "
          f"({cal['wrong_best']} with a wrong best angle): highest score of a wrong rotation "
          f"{cal['max_wrong_angle_score']:.3f}; proposed --score-min {cal['threshold']:g} "
          f"({cal['correct_at_or_above']} of {cal['correct_best']} right alignments reach it)")
    if args.out:
        write_files({args.out / "ncc_calibration.json":
                     jsonout.dumps({"calibration": cal, "hypotheses": rows}).encode()})
    return 0


# --- circsim sweep -----------------------------------------------------------------------------------
def register_sweep(sub) -> None:
    p = sub.add_parser("sweep", help="run every grid combination × seed; one tidy table and plots",
                       description="Every combination of --grid values × --seeds is one run (seed = base + i). "
                                   "Rows go to OUT/runs.jsonl as runs finish, then runs.csv, runs.parquet, "
                                   "summary.csv and sweep.png.")
    p.add_argument("scenario", help="scenario file or bundled name")
    p.add_argument("--grid", action="append", default=[], metavar="KEY.PATH=V1,V2,...",
                   help="a swept scenario key and its values, e.g. center_error=0,0.1,0.2 "
                        "(alias of center_error.magnitude_m) or network.latency_s=0,1,3 (repeatable)")
    p.add_argument("--seeds", type=int, default=5, help="seeds per combination (default 5)")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.add_argument("--workers", type=int, help="local worker processes (default: all cores)")
    p.add_argument("--dask", metavar="ADDRESS", help="run on an existing dask.distributed scheduler instead")
    p.add_argument("--resume", action="store_true", help="skip the runs already in OUT/runs.jsonl")
    p.add_argument("--overwrite", action="store_true", help="discard OUT/runs.jsonl and start again")
    p.add_argument("--no-plots", action="store_true", help="tables only")
    _scenario_args(p)
    p.set_defaults(func=cmd_sweep)


def cmd_sweep(args) -> int:
    """``circsim sweep``: :func:`circsim.experiments.api.run_sweep` with the options, and its report."""
    from ..commands import begin_work, interrupted_code
    from .api import SweepInterrupted, run_sweep
    from .plan import SweepError
    from .tables import counted, format_summary

    if args.workers is not None and args.workers < 1:
        raise SweepError(f"--workers: expected an integer >= 1, got {args.workers}")
    if args.dask:
        from .sweep import check_dask

        check_dask()

    def announce(base, axes, tasks, done, todo) -> None:
        begin_work()
        if base.merger.method == "reference" and todo and not args.quiet:
            print("circsim: note: merger.method is 'reference' (~3 s per merge cycle); "
                  "--set merger.method=fast is ~100x faster", file=sys.stderr)
        where = (f"dask {args.dask}" if args.dask else counted(args.workers, "local worker") if args.workers
                 else "all local workers")
        print(f"sweep {base.name}: {counted(len(tasks), 'run')} ({counted(len(tasks) // args.seeds, 'combination')}"
              f" × {counted(args.seeds, 'seed')}), {done} already done, {len(todo)} to run on {where}",
              file=sys.stderr)

    interrupted = False
    try:
        res = run_sweep(args.scenario, grid=args.grid, seeds=args.seeds, sets=args.set, seed=args.seed,
                        out=args.out, workers=args.workers, dask=args.dask, resume=args.resume,
                        overwrite=args.overwrite, plots=not args.no_plots, progress=not args.quiet,
                        on_start=announce, out_key="--out")
    except SweepInterrupted as e:
        res, interrupted = e.result, True
    if res.rows:
        from .plan import parse_grid

        print(format_summary(res.summary, parse_grid(args.grid)))
        print("written: " + ", ".join(str(p) for p in [args.out / "runs.jsonl", *res.paths]))
    if interrupted:
        print(f"circsim: interrupted; {len(res.rows)} of {res.planned} runs are in {args.out / 'runs.jsonl'} "
              "(--resume continues)", file=sys.stderr)
        return interrupted_code()
    if res.failed:
        print(f"circsim: {counted(res.failed, 'run')} failed (tracebacks in {args.out / 'errors.jsonl'}; --resume "
              "retries them)", file=sys.stderr)
        return 1
    return 0


# --- circsim score ----------------------------------------------------------------------------------
def register_score(sub) -> None:
    p = sub.add_parser("score", help="judge a merger's answers on a bag of `circsim run --bag` (its truth, "
                                     "the run's metrics)",
                       description="Judge an external merger against a run's ground truth with the run's "
                                   "metrics: first correct merge per robot, false merges, final errors "
                                   "(docs/ros.md).")
    p.add_argument("run", type=Path, metavar="RUN", help="the bag folder written by `circsim run --bag RUN`")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--transforms", type=Path, metavar="FILE",
                   help="CSV (or YAML) rows t_s,robot,map,yaw_deg,x_m,y_m[,estimate]: the pose of map's frame in "
                        "robot's map frame at t_s (RUN/circsim_merges.csv: the bench's own merges)")
    g.add_argument("--merged-bag", type=Path, metavar="BAG",
                   help="a bag with the merger's merged nav_msgs/OccupancyGrid (--topic): each robot's map is "
                        "located in it")
    p.add_argument("--topic", default="/map", help="the merged map topic in --merged-bag (default /map)")
    p.add_argument("--every", type=float, default=5.0, metavar="S",
                   help="--merged-bag: judge at most one merged map per S simulated seconds (default 5)")
    p.add_argument("--json", type=Path, metavar="OUT.json", help="write the scores as JSON")
    p.set_defaults(func=cmd_score)


def cmd_score(args) -> int:
    from .. import score as scoring

    if not (math.isfinite(args.every) and args.every > 0):  # nan passed `<= 0`
        raise ValueError(f"--every: expected a finite number of seconds > 0, got {args.every:g}")
    if args.json:  # never over an input (the truth, the transforms, a bag's files)
        from merger.io.mapio import check_outputs

        run_files = [*args.run.iterdir()] if args.run.is_dir() else [args.run]
        merged = [*args.merged_bag.iterdir()] if args.merged_bag and args.merged_bag.is_dir() else []
        check_outputs({args.json: "--json"}, {p: "RUN" for p in run_files} | {p: "--merged-bag" for p in merged}
                      | ({args.transforms: "--transforms"} if args.transforms else {}))
    truth = scoring.load_truth(args.run)
    if args.transforms:
        estimates = scoring.read_transforms(args.transforms, truth)
        what = str(args.transforms)
    else:
        from ..locate import merged_estimates

        estimates = merged_estimates(truth, args.run, args.merged_bag, args.topic, args.every)
        what = f"{args.merged_bag} {args.topic}"
    d = scoring.score(truth, estimates)
    print(scoring.summary(d, what))
    if args.json:
        write_files({args.json: jsonout.dumps(d, indent=2).encode()})
        print(f"scores:    {args.json}")
    return 0


REGISTER: list = [register_offline, register_sweep, register_score]
