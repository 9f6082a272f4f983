"""Command line: ``circsim run | scenarios | view`` (and the experiment commands).

A user's mistake (bad scenario, bad argument, missing file) prints one line ``circsim: error: ...``
and exits with 2, before any work and with nothing written; whatever was already computed or recorded
is kept. SIGTERM is handled as Ctrl-C (``circsim run`` stops at the end of the tick and completes its
recording, JSON and maps; a sweep stops its workers and writes its tables), exit code 143. Outputs are
written atomically (temporary file, then rename): a reader never sees half a file.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from . import commands
from .commands import (
    UsageError,
    add_scenario_args,
    begin_work,
    interrupted_code,
    load_with_overrides,
    progress_observer,
    resolve_scenario,
)

# the scenario module (numpy, OpenCV, the merger) is imported inside main: a Ctrl-C while it loads is
# then one line, not a traceback


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UsageError(message)


def build_parser() -> argparse.ArgumentParser:
    from merger.cli import package_version

    p = _Parser(prog="circsim", description="Simulation bench for multi-robot map merging with a common center.",
                epilog="Limits (checked before any work; docs/limits.md and `circsim scenarios --reference`): "
                       "scenario files up to 1 MiB, robots' grids up to 4000 cells a side, 1,000,000 ticks, "
                       "merger.roi_m up to 100 m. Errors: one line, exit 2; outputs are written to a temporary "
                       "file and renamed, never over an input or another output.")
    p.add_argument("--version", action="version", version=f"circsim {package_version()}")
    sub = p.add_subparsers(dest="cmd", required=True, parser_class=_Parser)
    r = sub.add_parser("run", help="run a scenario and print a summary")
    add_scenario_args(r)
    r.add_argument("--json", type=Path, metavar="OUT.json", help="write the run's metrics as JSON")
    r.add_argument("--rrd", type=Path, metavar="RUN.rrd", help="record the run to a rerun file")
    r.add_argument("--png", type=Path, metavar="REPORT.png",
                   help="write a static report of the run: the last merged map with every robot's map in its "
                        "colour, ν over time with false merges marked, each robot's first correct merge")
    r.add_argument("--spawn", action="store_true", help="stream the run to a live rerun viewer")
    r.add_argument("--save-maps", type=Path, metavar="DIR",
                   help="write every robot's last published map as ROS map_server files (DIR/<robot>.yaml/.pgm) "
                        "and DIR/centers.yaml: each map's center (given and true), the robots' start poses, the "
                        "ground truth onto the first robot's map and the `merger merge` command that merges them")
    r.add_argument("--bag", type=Path, metavar="OUT",
                   help="write the run as a ROS 2 bag (folder OUT, MCAP): every robot's map, scans, odometry and "
                        "tf, with the ground truth and the bench's merges beside (OUT/circsim_truth.yaml, "
                        "OUT/circsim_merges.csv; `circsim score`); needs pip install -e \".[ros]\"")
    r.add_argument("--quiet", action="store_true",
                   help="no progress on stderr (by default a bar on a terminal, else a line every 5 s of work)")
    sc = sub.add_parser("scenarios", help="list the bundled scenarios (--show NAME: one in full)")
    sc.add_argument("--show", metavar="SCENARIO", help="print a scenario (bundled name or file) with every key "
                                                       "and its value, defaults filled in, as YAML")
    sc.add_argument("--reference", action="store_true", help="print the scenario reference (every key, its "
                                                             "default and what is expected; docs/scenario-reference.md)")
    v = sub.add_parser("view", help="open a recorded run (.rrd) in the rerun viewer")
    v.add_argument("rrd", type=Path, help="a recording written by `circsim run --rrd RUN.rrd`")
    v.add_argument("--web", action="store_true", help="serve the web viewer on 127.0.0.1 instead")
    for register in extra_commands():
        register(sub)
    return p


def extra_commands():
    """Experiment commands that live in their own modules (each module adds its subparser)."""
    from .experiments import cli as experiments_cli

    return experiments_cli.REGISTER


def summary(res) -> str:
    from .metrics import false_merge_lines, slam_lines

    d = res.to_dict()
    lines = [f"scenario {d['scenario']}  seed {d['seed']}  simulated {d['sim_s']:.1f} s in {d['wall_s']:.1f} s "
             f"(realtime factor {d['realtime_factor'] or float('inf'):.1f})"
             + ("  [INTERRUPTED]" if d["interrupted"] else ""), "",
             f"{'robot':<10} {'first merge s':>13} {'arc deg':>8} {'cycles':>7} {'accepted':>9} "
             f"{'false':>6} {'rej.correct':>11}  final errors per teammate (angle deg / translation cm)"]
    for n, r in d["robots"].items():
        fm = "—" if r["first_merge_s"] is None else f"{r['first_merge_s']:.1f}"
        arc = "—" if r["first_merge_arc_deg"] is None else f"{r['first_merge_arc_deg']:.1f}"
        errs = r["final_angle_error_deg"] or {}
        t_errs = r.get("final_translation_error_m") or {}
        e = ", ".join(f"{k} {v:.2f}° / " + ("—" if k not in t_errs else f"{100 * t_errs[k]:.1f} cm")
                      for k, v in errs.items() if k != n) or "—"
        lines.append(f"{n:<10} {fm:>13} {arc:>8} {r['cycles']:>7} {r['accepted']:>9} {r['false_merges']:>6} "
                     f"{r['rejected_correct']:>11}  {e}")
    mc = d["merge_cycle_ms"]
    lines += ["", f"false merges {d['false_merges']}   rejected correct {d['rejected_correct']}   "
              + (f"merge cycle cost median {mc['median']:.1f} ms, p95 {mc['p95']:.1f} ms "
                 f"({mc['count']} cycle{'' if mc['count'] == 1 else 's'})"
                 if mc["count"] else "no merge cycle")]
    lines += false_merge_lines(d) + slam_lines(d)
    cs = d.get("consensus_s")
    lines.append("consensus (every robot holds the same global alignment): "
                 + ("never" if cs is None else f"first at {cs:.1f} s, held {d['consensus_held_s']:.1f} s in all"
                    + ("" if d["consensus_final"] else ", not at the end"))
                 + ("   shared hypotheses adopted " + ", ".join(f"{n} {r['hypotheses_adopted']}/{r['hypotheses_received']}"
                                                        for n, r in d["robots"].items())
                    if any(r["hypotheses_received"] for r in d["robots"].values()) else ""))
    lat, tr, j = d.get("latency_s") or {}, d.get("tracking") or {}, d.get("placement_jump") or {}
    if lat.get("count"):
        lines.append(f"map version to its first verified merge: median {lat['median']:.1f} s, p95 {lat['p95']:.1f} s"
                     + (f"; placement jumps p95 {j['deg_p95']:.2f}° / {100 * j['m_p95']:.1f} cm"
                        if j.get("count") else ""))
    if tr.get("per_robot"):
        lines.append(f"tracking (merger.research on_change): {tr['global_searches']} global searches, "
                     f"{tr['local_checks']} local re-verifications, {tr.get('held', 0)} answers held, "
                     f"{tr.get('waited', 0)} versions waited for support, "
                     f"{tr['switches']} switches (summed over the robots)")
    return "\n".join(lines)


def cmd_run(args) -> int:
    from merger.io.mapio import write_files
    from merger.io.mapread import MapFileError

    from .outputs import check_bag_output, check_maps_folder, check_run_outputs, make_folders, writable
    from .sim import Simulation

    sc = load_with_overrides(args.scenario, args.seed, args.set)
    if sc.robots.motion == "offline":
        raise UsageError(f"{sc.source}: robots.motion: offline is the displacement experiment (robots moved "
                         f"±φ step by step, maps saved at each step): run `circsim offline {args.scenario}` "
                         "(with --out DIR --save-maps for the maps); `circsim run` drives the robots online")
    rrd = args.rrd or (Path(sc.output.rrd) if sc.output.rrd else None)
    json_out = args.json or (Path(sc.output.json) if sc.output.json else None)
    # every check before the first tick, and none creates anything (issue 46): then the folders are made
    if rrd:
        writable(rrd, "recording")
    if json_out:
        writable(json_out, "metrics JSON")
    if args.png:
        writable(args.png, "report picture")
    check_run_outputs(sc, args.scenario, rrd, json_out, args.save_maps, args.bag, args.png)
    if args.bag:
        check_bag_output(args.bag)
    if args.save_maps:
        check_maps_folder(args.save_maps)
    make_folders(args.save_maps, rrd.parent if rrd else None)
    if sc.world.generate is not None:  # where the generated plan put the common center
        from .config.floorplanworld import describe

        print(describe(sc.world), flush=True)
    observers = [o for o in [progress_observer(sc, args.quiet)] if o]
    from .record.savemaps import MapSaver

    saver = MapSaver() if args.save_maps else None
    if saver:
        observers.append(saver)
    bag = None
    if args.bag:
        from .record.bag import BagRecorder

        bag = BagRecorder(args.bag)
        observers.append(bag)
    report = None
    if args.png:
        from .report import RunReport

        report = RunReport()
        observers.append(report)
    recorder = None
    if rrd or args.spawn:
        from .record.rerun import RerunRecorder

        recorder = RerunRecorder(str(rrd) if rrd else None, spawn=args.spawn, scan_log_hz=sc.output.scan_log_hz,
                                 merged_log_period_s=sc.output.merged_log_period_s)
        observers.append(recorder)
    begin_work()
    try:
        res = Simulation(sc, observers).run()
    except ValueError as e:
        if bag is not None:
            bag.abort()
        if recorder is not None and recorder.stuck:  # nothing was run yet; rerun's exit hook would block forever
            print(f"circsim: error: {e}", file=sys.stderr, flush=True)
            sys.stdout.flush()
            os._exit(2)
        raise
    rrd_error = recorder.write_error if recorder else None
    if rrd and not rrd_error:
        res.outputs["rrd"] = str(rrd)
    if json_out:
        res.outputs["json"] = str(json_out)
    if bag is not None and not bag.write_error:
        res.outputs["bag"] = str(args.bag)
    if saver:
        res.outputs["maps"] = str(args.save_maps)
    print(summary(res))  # first: whatever happens to the files, the figures are on screen
    failed = False
    if rrd_error:
        print(f"circsim: error: {rrd_error}; the run's figures are above", file=sys.stderr)
        failed = True
    elif rrd:
        print(f"recording: {rrd}   (view it: circsim view {rrd})")
    if bag is not None:
        if bag.write_error:
            print(f"circsim: error: {bag.write_error}; the run's figures are above", file=sys.stderr)
            failed = True
        else:
            print(f"bag:       {args.bag}   (score a merger on it: circsim score {args.bag} --transforms FILE)")
    if saver:
        try:
            files = saver.files(args.save_maps)
            write_files(files)
            print(f"maps:      {len(saver.grids)} robots' last maps and "
                  f"{args.save_maps / 'centers.yaml'} in {args.save_maps}" if files else
                  "maps:      no map was published; nothing written")
        except MapFileError as e:
            print(f"circsim: error: --save-maps: {e}; the run's figures are above", file=sys.stderr)
            failed = True
    if report is not None:
        try:
            write_files({args.png: report.png()})
            print(f"report:    {args.png}")
        except MapFileError as e:
            print(f"circsim: error: {args.png}: cannot write the report ({e}); the run's figures are above",
                  file=sys.stderr)
            failed = True
    if json_out:
        from .record import jsonout

        try:
            write_files({json_out: jsonout.dumps(res.to_dict(), indent=2).encode()})  # 8.6, not 8.600000000000001
            print(f"metrics:   {json_out}")
        except MapFileError as e:
            print(f"circsim: error: {json_out}: cannot write the metrics JSON ({e}); "
                  f"the run's figures are above", file=sys.stderr)
            failed = True
    if failed:
        if recorder is not None and recorder.stuck:  # rerun's exit hook would block forever on its dead writer
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(2)
        return 2
    return interrupted_code() if res.interrupted else 0


def cmd_scenarios(args) -> int:
    from .config.scenario import ScenarioError, bundled_scenarios, load_scenario, scenario_to_dict

    if args.reference:
        from .config.reference_doc import scenario_reference

        print(scenario_reference(), end="")
        return 0
    if args.show:
        import yaml

        sc = load_scenario(resolve_scenario(args.show))
        print(f"# {sc.source}, every key with its value (defaults filled in); ALIASES for --set/--grid: "
              "center_error, latency, network.latency/jitter/period")
        print(yaml.safe_dump({"name": sc.name, "description": sc.description, "seed": sc.seed,
                              "duration_s": sc.duration_s, "dt_s": sc.dt_s, **scenario_to_dict(sc)},
                             sort_keys=False, default_flow_style=None, allow_unicode=True, width=110), end="")
        return 0
    for name, path in bundled_scenarios().items():
        try:
            sc = load_scenario(path)
            print(f"{name:<16} {sc.description}")
        except ScenarioError as e:
            print(f"{name:<16} (invalid: {e})")
    return 0


def cmd_view(args) -> int:
    from .record.viewer import view

    begin_work()
    return view(args.rrd, web=args.web)


COMMANDS = {"run": cmd_run, "scenarios": cmd_scenarios, "view": cmd_view}


def main(argv=None) -> int:
    saved = commands.start()
    try:
        return _main(argv)
    finally:
        commands.finish(saved)


def _main(argv=None) -> int:
    try:
        args = build_parser().parse_args(argv)
        from merger.team.pool import threads

        threads()  # MERGER_THREADS=abc: refused before any work (ValueError), not "every core"
        fn = COMMANDS.get(args.cmd) or args.func
        return fn(args)
    except KeyboardInterrupt:
        print("circsim: terminated" if commands.terminated() else "circsim: interrupted", file=sys.stderr)
        return commands.interrupted_code()
    except BrokenPipeError:  # `circsim scenarios | head -1`: the reader left; not an error (Python docs' way)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at interpreter exit
        return 1
    except Exception as e:
        from .config.scenario import ScenarioError

        if isinstance(e, UsageError | ScenarioError | FileNotFoundError | ValueError):
            print(f"circsim: error: {e}", file=sys.stderr)
            return 2
        if isinstance(e, OSError):  # a file the user named cannot be read or written
            print(f"circsim: error: {f'{e.filename}: ' if e.filename else ''}{e.strerror or e}", file=sys.stderr)
            return 2
        raise


if __name__ == "__main__":
    sys.exit(main())
