"""The ``swarmform`` command line.

Exit codes: 0 success; 1 no plan within the limits, or the physics run saw
a contact or missed a target (the report is still written); 2 wrong input
(one line of at most 200 characters naming the file or option, the field
and the reason; no traceback; nothing written), argument errors of every
subcommand included; 3 an internal error (one line; ``swarmform --debug``
shows the traceback).  No exception reaches the user as exit 1.  Output
paths are checked before any input is read or any work done.
"""

from __future__ import annotations

import argparse
import errno
import sys
import time
from pathlib import Path

from .argtypes import int_in, seconds

__all__ = ["LINE_MAX", "main"]

EXIT_OK, EXIT_FAIL, EXIT_INPUT, EXIT_INTERNAL = 0, 1, 2, 3

LINE_MAX = 200
"""The longest error line the command prints [characters]."""


def _one_line(text: str, limit: int = LINE_MAX) -> str:
    """``text`` on one line of at most ``limit`` characters.

    A longer text keeps its beginning (the command, the file, the field)
    and its end (most often what to do), cut in the middle with `` ... ``.
    """
    text = " ".join(str(text).split())
    if len(text) <= limit:
        return text
    head = (limit * 3) // 5
    return text[:head] + " ... " + text[-(limit - head - 5):]


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (exit 2), like wrong files."""

    def error(self, message: str):
        hint = f" (see {self.prog} --help)"
        line = _one_line(f"{self.prog}: error: {message}", LINE_MAX - len(hint)) + hint
        self.exit(EXIT_INPUT, _one_line(line) + "\n")


def _cmd_formations(args) -> int:
    from planner.formations import DEFAULT_COUNTS

    print("formation  default count (paper Table I)")
    for name, count in DEFAULT_COUNTS.items():
        print(f"{name:<10} {count if count is not None else 'needs robots.count'}")
    print("scatter    needs robots.count (spread over the free space, or over region: [x0, y0, x1, y1])")
    print("text       from the text's size, or robots.count ({text: WORDS, font: FILE.ttf, fill: strokes|area})")
    print("strokes    from the strokes' length, or robots.count ({strokes: [[[x, y], ...], ...]} in a unit box)")
    return EXIT_OK


def _load(path: str, seed: int | None):
    """Read a scenario and build its problem with the run's one generator."""

    from .scenario import build_problem, read_scenario

    scenario = read_scenario(path)
    seed = scenario.seed if seed is None else seed
    rng = scenario.generator(seed)
    problem = build_problem(scenario, rng)
    return scenario, seed, rng, problem


def _cmd_show(args) -> int:
    from .output.files import OutputPathError, check_out_file
    from .output.media import write_png
    from .output.render import draw_scenario

    if args.output:
        check_out_file(args.output, "--output")
        if Path(args.output).suffix.lower() != ".png":
            raise OutputPathError("--output", args.output, "show writes PNG images only; give a name ending in .png")
    scenario, seed, _rng, problem = _load(args.scenario, args.seed)
    out = Path(args.output) if args.output else Path("media") / f"{scenario.name}-scenario.png"
    if not args.output:
        check_out_file(out, "--output")
    title = f"{scenario.name}  seed {seed}"
    image = draw_scenario(problem, size=args.size, title=title)
    write_png(out, image)
    print(f"wrote {out}  ({scenario.describe()}, m={problem.m})")
    return EXIT_OK


def _print_stats(stats, margin: float, out=None, *, auto: bool = False):
    out = sys.stdout if out is None else out  # looked up at the call (a redirected stdout too)
    rows = [
        ("found", "yes" if stats.found else "no"),
        ("planning time", f"{stats.planning_time_s:.3f} s"),
        ("g, q", "auto, auto" if auto else f"{stats.g}, {stats.q}"),
        ("pebble graphs", f"{stats.graphs} sampled"),
        ("connections", f"{stats.connections}"),
    ]
    if stats.found:
        rows += [
            ("steps", f"{stats.steps}"),
            ("makespan", f"{stats.makespan_s:.2f} s"),
            ("path length", f"{stats.path_length:.2f}"),
            ("min clearance", f"{stats.min_clearance:.4f} (margin {margin:g})"),
        ]
        if stats.makespan_lower_bound_s == stats.makespan_lower_bound_s:  # not NaN
            rows += [
                ("makespan bound", f"{stats.makespan_lower_bound_s:.2f} s "
                 f"(plan is {stats.makespan_s / max(stats.makespan_lower_bound_s, 1e-9):.2f}x)"),
                ("length bound", f"{stats.path_length_lower_bound:.2f}"),
            ]
        # the bounds that respect obstacles (shortest paths around them; narrow passages)
        for key, name, why in (("makespan_lower_bound_geo_s", "geo bound", "geo_lower_bound"),
                               ("makespan_lower_bound_cut_s", "cut bound", "cut_lower_bound")):
            value = getattr(stats, key, float("nan"))
            if value == value and value > 0:
                rows.append((name, f"{value:.2f} s (plan is {stats.makespan_s / value:.2f}x)"))
            elif isinstance(stats.extra.get(why), str) and ("budget" in stats.extra[why]):
                rows.append((name, stats.extra[why]))
    for key, value in rows:
        print(f"  {key:<15} {value}", file=out)


_SET_HELP = "set a scenario field (dotted path, YAML scalar), e.g. --set robots.margin=0.2; repeatable"


def _cmd_plan(args) -> int:
    from planner import NoPlanFound
    from planner.visible import Late

    from .execute.legs import plan_legs
    from .output.files import check_out_file
    from .output.media import atomic_path
    from .scenario import build_legs, read_scenario
    from .scenario.overrides import combinations, parse_set

    if args.output:
        check_out_file(args.output, "--output")
    overrides = combinations([parse_set(text, many=False) for text in args.set])[0]
    t0 = getattr(args, "started", None) or time.perf_counter()  # the command's start: imports count
    scenario = read_scenario(args.scenario, overrides=overrides)
    seed = scenario.seed if args.seed is None else args.seed
    rng = scenario.generator(seed)
    limit = scenario.planner_params(args.time_limit).time_limit
    try:
        problem, targets = build_legs(scenario, rng, deadline=t0 + limit)
    except Late:
        print(f"no plan: the time limit of {limit:g} s ran out while the robots were being placed", file=sys.stderr)
        return EXIT_FAIL
    out = Path(args.output) if args.output else Path("media") / f"{scenario.name}-plan.json"
    if not args.output:
        check_out_file(out, "--output")
    params = scenario.planner_params(args.time_limit, spent=time.perf_counter() - t0)
    mode = "auto" if params.auto else f"g={params.g} q={params.q}"
    print(f"{scenario.name} (seed {seed}): {problem.m} robots, {scenario.describe()}, {mode}")
    try:
        result, stats, _ = plan_legs(problem, targets, params, rng, holds=[t.hold for t in scenario.legs],
                                     labels=[t.describe() for t in scenario.legs])
    except NoPlanFound as exc:
        _print_stats(exc.stats, problem.margin, auto=params.auto)
        proven = exc.stats.extra.get("feasible") is False  # the message says "no plan exists: ..."
        print(str(exc) if proven else f"no plan: {exc}", file=sys.stderr)
        return EXIT_FAIL
    _print_stats(stats, problem.margin, auto=params.auto)
    with atomic_path(out) as tmp:
        extra = {"scenario": scenario.name, "seed": seed}
        if scenario.map_origin is not None:
            extra["origin"] = list(scenario.map_origin)
        tmp.write_text(result.to_json(extra), encoding="utf-8")
    print(f"wrote {out}")
    return EXIT_OK


def _cmd_run(args) -> int:
    from .runner import run_scenario
    from .scenario.overrides import combinations, parse_set

    result = run_scenario(
        args.scenario,
        seed=args.seed,
        out_dir=args.out,
        render=not args.no_render,
        plan_path=args.plan,
        time_limit=args.time_limit,
        overrides=combinations([parse_set(text, many=False) for text in args.set])[0],
        started=getattr(args, "started", None),
    )
    from .output.report import verdict

    print(f"  {verdict(result.report)[1]}")
    return result.exit_code


def _number_in(low: float, high: float, what: str):
    """A parser for finite numbers in ``(low, high]``, said as ``what``."""

    def parse(value: str) -> float:
        import math

        try:
            v = float(value) if len(value) <= 40 else math.nan
        except ValueError:
            v = math.nan
        if not (math.isfinite(v) and low < v <= high):
            raise argparse.ArgumentTypeError(f"must be {what} in ({low:g}, {high:g}], got {value[:40]!r}")
        return v

    return parse


def _cmd_export(args) -> int:
    from .output.export import cmd_export

    return cmd_export(args)


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("swarmform")
    except PackageNotFoundError:
        return "(not installed)"


_DEBUG_HELP = "on an internal error (exit 3), show the traceback"
_SEED = int_in(0, 2**63 - 1)


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="swarmform",
        description="Switch a swarm of disc robots between formations: plan with UPUMP, "
        "check the plan exactly, execute it in pymunk and render it.",
        epilog="exit codes: 0 success; 1 no plan, or a contact or missed target in physics; "
        "2 wrong input (one line); 3 internal error (one line; --debug shows the traceback)",
    )
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    p.add_argument("--debug", action="store_true", help=_DEBUG_HELP)
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    common = _Parser(add_help=False)
    common.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=_DEBUG_HELP)

    f = sub.add_parser("formations", help="list the formations and their default robot counts", parents=[common])
    f.set_defaults(func=_cmd_formations)

    s = sub.add_parser("show", help="draw a scenario (start hollow, target filled) to a PNG", parents=[common])
    s.add_argument("scenario", help="scenario YAML file")
    s.add_argument("--seed", type=_SEED, help="override the scenario's seed")
    s.add_argument("-o", "--output", help="PNG file (default media/NAME-scenario.png)")
    s.add_argument("--size", type=int_in(64, 4096), default=None,
                   help="picture side in pixels, 64 to 4096 (default: grows with the workspace and m, 480 to 960)")
    s.set_defaults(func=_cmd_show)

    pl = sub.add_parser("plan", help="plan a scenario and write the plan JSON (with its stats)", parents=[common])
    pl.add_argument("scenario", help="scenario YAML file")
    pl.add_argument("--seed", type=_SEED, help="override the scenario's seed")
    pl.add_argument("-o", "--output", help="plan JSON file (default media/NAME-plan.json)")
    pl.add_argument("--time-limit", type=seconds, help="override planner.time_limit [s]")
    pl.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help=_SET_HELP)
    pl.set_defaults(func=_cmd_plan)

    r = sub.add_parser(
        "run",
        help="plan (or load a plan), validate, execute in physics, render; "
        "write DIR/NAME.json, the video and the page DIR/NAME.html",
        parents=[common],
    )
    r.add_argument("scenario", help="scenario YAML file")
    r.add_argument("--seed", type=_SEED, help="override the scenario's (or the plan file's) seed")
    r.add_argument("--out", default="media", help="output folder (default media/)")
    r.add_argument("--no-render", action="store_true", help="skip the video")
    r.add_argument("--plan", help="execute this plan JSON as it is instead of planning")
    r.add_argument("--time-limit", type=seconds, help="override planner.time_limit [s]")
    r.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help=_SET_HELP)
    r.set_defaults(func=_cmd_run)

    from .check import add_check_parser

    add_check_parser(sub, parents=[common])

    e = sub.add_parser(
        "export", parents=[common],
        help="write a plan's trajectories: samples (csv, json) or exact polynomials (poly, Crazyswarm CSV)",
        description="Write a plan file's trajectories.  csv and json: position and velocity of every robot "
        "at --rate Hz and at the final time (csv columns robot,t,x,y,vx,vy; json "
        '{"rate", "makespan", "robots": [{"t", "x", "y", "vx", "vy"}]}), to -o FILE or standard output.  '
        "poly: per robot, one piece per plan step, the exact degree-5 minimum-jerk polynomial, in the CSV "
        "format of Crazyswarm's uploadTrajectory (duration,x^0..x^7,y^0..y^7,z^0..z^7,yaw^0..yaw^7), "
        "one file DIR/robotNNN.csv per robot.",
    )
    e.add_argument("plan", help="plan JSON file (swarmform plan writes one)")
    e.add_argument("--format", choices=("csv", "json", "poly"), default="csv", help="output format (default csv)")
    e.add_argument("--rate", type=_number_in(0, 10_000, "a number of samples per second"), default=20.0,
                   help="csv, json: samples per second [Hz] (default 20)")
    e.add_argument("--height", type=_number_in(-1e6, 1e6, "a number of workspace units"), default=0.0,
                   help="poly: the constant z of every trajectory [workspace units] (default 0)")
    e.add_argument("--origin", nargs=2, metavar=("X", "Y"), default=None,
                   type=_number_in(-1e9, 1e9, "a number of workspace units"),
                   help="added to every position: the world position of the workspace's lower-left corner "
                   "(default the plan file's origin, which swarmform plan records from a map's origin, else 0 0)")
    e.add_argument("-o", "--output", metavar="FILE_OR_DIR",
                   help="csv, json: the file (default standard output); poly: the folder "
                   "(default PLAN-poly beside the plan file)")
    e.set_defaults(func=_cmd_export)

    from .tune.cli import add_tune_parser

    t = add_tune_parser(sub)
    t.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=_DEBUG_HELP)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return its exit code (see the module docstring)."""
    started = time.perf_counter()  # a time limit covers the whole command, its imports too
    argv = sys.argv[1:] if argv is None else list(argv)
    debug = "--debug" in argv
    from .stops import Stopped, stop_handlers

    args = None
    try:
        with stop_handlers():
            parser = build_parser()
            args = parser.parse_args(argv)
            args.started = started
            debug = debug or bool(getattr(args, "debug", False))
            return args.func(args)
    except SystemExit:  # --help, --version, argument errors: before the error classes are imported
        raise
    except _input_errors() as exc:
        _say(f"swarmform: error: {exc}")
        return EXIT_INPUT
    except Stopped as exc:  # SIGTERM, SIGHUP, SIGQUIT: cleaned up as for Ctrl-C
        _say(f"swarmform: stopped by {exc.args[0]}")
        return exc.exit_code
    except KeyboardInterrupt:
        _say("swarmform: interrupted")
        return 130
    except BrokenPipeError:  # standard output closed early (swarmform ... | head)
        _silence_stdout()
        _say("swarmform: standard output was closed (broken pipe); stopped")
        return 141  # as if killed by SIGPIPE, as the shell reports it
    except OSError as exc:
        if exc.errno != errno.ENOSPC:
            return _internal(exc, debug)
        where = exc.filename or getattr(args, "output", None) or getattr(args, "out", None) or "the output"
        _say(f"swarmform: error: {where}: no space left on device")
        return EXIT_INPUT
    except Exception as exc:  # noqa: BLE001 - anything else is a defect: one line, exit 3
        return _internal(exc, debug)


def _internal(exc: BaseException, debug: bool) -> int:
    """Say an internal error in one line (with ``--debug``, the traceback first); exit 3."""
    if debug:
        import traceback

        traceback.print_exception(exc)
    kind = type(exc).__name__
    hint = "" if debug else " (swarmform --debug ... shows the traceback)"
    _say(_one_line(f"swarmform: internal error: {kind}: {exc}", LINE_MAX - len(hint)) + hint)
    return EXIT_INTERNAL


def _input_errors() -> tuple[type[BaseException], ...]:
    from planner import PlanFileError, ProblemError

    from .errors import InputError
    from .scenario import ScenarioError

    return ScenarioError, ProblemError, PlanFileError, InputError


def _say(line: str) -> None:
    try:
        print(_one_line(line), file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


def _silence_stdout() -> None:
    import os

    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except (OSError, ValueError):
        pass


if __name__ == "__main__":
    sys.exit(main())
