"""Command line: ``merger align``, ``merger merge`` and ``merger demo``.

A user's mistake (bad file, bad argument) prints one line ``merger: error: ...`` and exits with 2, before
any work and with nothing written. The limits it checks are :mod:`merger.limits` (shared with circsim);
the file formats are :mod:`merger.io`; every check of a merge's inputs is the library's
(:mod:`merger.inputs`), named here by the option the user typed.

The package: :mod:`.parser` (the grammar, :data:`OPTIONS`), :mod:`.checks` (the command line's own
checks: ``X,Y`` text, centers per map, outputs, the demo's options), :mod:`.report` (the text, JSON and
files of an answer), :mod:`.commands` (the three commands). Here: :func:`main`, and :func:`params_from`,
the merge settings every command checks first.
"""

from __future__ import annotations

import sys

from ..io.mapio import write_files
from ..io.mapread import MapFileError
from ..settings import check_roi as roi_rule
from ..settings import check_window
from ..team.params import RULES, MergeParams
from ..team.pool import threads
from .checks import (
    DEMO_MAX_RADIUS_M,
    DEMO_MAX_RADIUS_REAL_M,
    bag_inputs,
    center_keys,
    centers_of,
    check_output_folder,
    check_roi,
    check_stem,
    file_inputs,
    map_names,
    options_named,
    pair_names,
    parse_xy,
)
from .commands import cmd_align, cmd_demo, cmd_merge
from .parser import (
    CLI_VERIFICATIONS,
    OPTIONS,
    UsageError,
    add_merge_options,
    build_parser,
    join_negative_xy,
    package_version,
)
from .report import (
    ascii_text,
    merge_files,
    order_mark,
    overlay_path,
    overlay_title,
    pose_lines,
    report_align,
    report_merge,
    verdict_line,
    write_merge,
)

__all__ = [
    "main", "params_from", "build_parser", "add_merge_options", "join_negative_xy", "package_version", "OPTIONS",
    "CLI_VERIFICATIONS", "UsageError", "parse_xy", "check_roi", "options_named", "map_names", "pair_names",
    "center_keys", "centers_of", "file_inputs", "bag_inputs", "check_output_folder", "check_stem",
    "DEMO_MAX_RADIUS_M", "DEMO_MAX_RADIUS_REAL_M", "report_align", "report_merge", "order_mark", "verdict_line",
    "pose_lines", "merge_files", "write_merge", "write_files", "overlay_path", "overlay_title", "ascii_text",
    "cmd_align", "cmd_merge", "cmd_demo", "exit_now",
]


def params_from(args) -> MergeParams:
    """The merge parameters of the command line (:data:`OPTIONS`; a command without an option takes
    MergeParams's default), every value checked first by its setting's one rule, named by its option (a
    one-line error); MergeParams's own ValueError is the last line of defence."""
    values = {name: getattr(args, dest) for name, (_, dest) in OPTIONS.items() if hasattr(args, dest)}
    try:
        roi_rule(args.roi, key="--roi", limits=True)  # the ROI's rule with the inputs' limits (merger.inputs)
        for name, v in values.items():
            RULES[name](v, OPTIONS[name][0])
        check_window(args.window, args.roi, "--window", "the --roi side")  # the rule between the two
    except ValueError as e:
        raise UsageError(str(e)) from None
    try:
        return MergeParams(**values)
    except ValueError as e:
        raise UsageError(f"invalid merge parameters: {e}") from None


def exit_now(code: int) -> None:
    """End the process at once with ``code``: Python's exit would first wait for the merge pool's threads to
    finish the searches they are running (compiled kernels cannot be interrupted). Nothing is lost: every
    output is written whole or not at all."""
    import os

    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


def main(argv=None) -> int:
    try:
        args = build_parser().parse_args(join_negative_xy(sys.argv[1:] if argv is None else list(argv)))
        threads()  # MERGER_THREADS=abc: refused before any work (ValueError), not "every core"
        args.params = params_from(args)  # every command merges: its settings checked first
        return {"align": cmd_align, "merge": cmd_merge, "demo": cmd_demo}[args.cmd](args)
    except (UsageError, MapFileError, ValueError) as e:
        print(f"merger: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # e.g. `merger merge ... --json | head`: the reader left, not an error of ours
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at interpreter exit
        return 1
    except OSError as e:  # a file the user named cannot be read or written
        print(f"merger: error: {f'{e.filename}: ' if e.filename else ''}{e.strerror or e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("merger: interrupted", file=sys.stderr)
        if argv is None:  # the program: out now, not after the pool's searches still running (26 s on 4224² maps)
            exit_now(130)
        return 130
