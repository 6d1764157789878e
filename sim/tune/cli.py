"""``swarmform tune``: the argparse parser and its commands."""

from __future__ import annotations

import argparse
import math
import sys
from collections import Counter
from collections.abc import Callable
from pathlib import Path

from ..argtypes import int_at_least, seconds
from .limits import BUILD_ALLOWANCE_S, PHYSICS_ALLOWANCE_S

# The sweep's machinery (the scenario reader, the planner, Dask) is imported by
# the commands that run, not here: building the parser, as ``--help`` does, stays
# a matter of milliseconds.

__all__ = ["EXIT_CLUSTER_LOST", "add_tune_parser"]

EXIT_OK, EXIT_INCOMPLETE, EXIT_CLUSTER_LOST = 0, 1, 4
"""0: every run has its row; 1: some runs have none (rerun); 4: the Dask scheduler was lost or too slow."""

_MAX_GRID = 1_000_000  # runs in one sweep

_TUNE_DESCRIPTION = f"""\
Run the grid of (scenario, settings, g, q, seed) planning runs, plus auto mode
with --auto, on local worker processes or an existing Dask cluster.  --set
KEY=V1,V2,... sweeps any scenario field (a dotted path into the YAML file);
several --set options make a grid.  Each finished run is appended at once to a
JSON Lines file; rerunning the same command skips the runs already there, so an
interrupted sweep is finished by running it again.  Then write a Markdown
summary, heatmaps over (g, q), contact-rate plots for --set sweeps with
--simulate, and an HTML page beside the results.

Every run has a watchdog: 1.1 x its planning time limit plus an allowance
({BUILD_ALLOWANCE_S:g} s to build the problem, {BUILD_ALLOWANCE_S + PHYSICS_ALLOWANCE_S:g} s with --simulate; --allowance
changes it).  A run whose watchdog fires, or whose worker dies, is a failed row
(Timeout / WorkerDied) and the other runs go on.

-o appends only to a results file of swarmform tune (empty, or every line a
result row), never through a symbolic link; anything else is refused (exit 2)
and left untouched."""

_TUNE_EPILOG = """\
exit status:
  0  every run of the grid has its row (whatever the planner found)
  1  some runs have no row (the cluster lost them); rerun to finish them
  2  bad input (including a Dask scheduler that cannot be reached; nothing is run)
  4  the Dask scheduler was lost mid-sweep, or a peer at --scheduler accepted the
     connection but did not answer in time; the rows so far are kept, rerun to finish

examples:
  swarmform tune scenarios/paper/fig2-random-to-C.yaml --g 1 2 3 --q 100 250 500 800 --auto
  swarmform tune scenarios/paper/fig1-line-to-phi.yaml --set robots.margin=0.1,0.2,0.4 \\
      --set sim.kp=100,400 --seeds 50 --simulate
  swarmform tune a.yaml b.yaml --g 2 3 --q 250 500 --scheduler tcp://HOST:8786
  swarmform tune --paper --seeds 20
  swarmform tune --summarize media/fig2-random-to-C-tune.jsonl"""


def add_tune_parser(sub) -> argparse.ArgumentParser:
    """Register ``swarmform tune`` on the CLI's subparsers."""
    t = sub.add_parser(
        "tune",
        help="sweep g, q and any scenario field (--set) over seeds (parallel, resumable) and summarise",
        description=_TUNE_DESCRIPTION,
        epilog=_TUNE_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    t.add_argument("scenarios", nargs="*", metavar="SCENARIO", help="scenario YAML files")
    t.add_argument("--g", nargs="+", type=int_at_least(1), metavar="G",
                   help="pebble graph counts to try (default: each scenario's planner.g)")
    t.add_argument("--q", nargs="+", type=int_at_least(1), metavar="Q",
                   help="connection attempts per pair of graphs to try (default: each scenario's planner.q)")
    t.add_argument("--auto", action="store_true", help="also run auto mode (g and q chosen by the planner)")
    t.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=V1,V2,...",
                   help="sweep a scenario field over these values (YAML scalars), e.g. robots.margin=0.1,0.2; "
                   "repeat for a grid over several fields")
    t.add_argument("--seeds", type=int_at_least(1), default=20, metavar="N",
                   help="seeds per setting (default 20): SEED_START .. SEED_START+N-1")
    t.add_argument("--seed-start", type=int_at_least(0), default=0, metavar="S", help="first seed (default 0)")
    t.add_argument("--time-limit", type=seconds, metavar="S",
                   help="planning time limit per run [s] (default: each scenario's planner.time_limit)")
    t.add_argument("--simulate", action="store_true",
                   help="also execute each plan in the physics world and record its verdict")
    t.add_argument("--allowance", type=_seconds_at_least_0, metavar="S",
                   help=f"seconds a run may take beyond 1.1 x its time limit before its watchdog stops it "
                   f"(default {BUILD_ALLOWANCE_S:g}, or {BUILD_ALLOWANCE_S + PHYSICS_ALLOWANCE_S:g} with --simulate)")
    t.add_argument("--workers", type=int_at_least(1), metavar="N",
                   help="local worker processes (default: the CPU count); with --scheduler, the most runs "
                   "in flight on the cluster (default: its thread count)")
    t.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on an existing Dask cluster, e.g. tcp://HOST:8786 (needs swarmform[cluster])")
    t.add_argument("-o", "--output", metavar="FILE",
                   help="results file (default media/NAME-tune.jsonl, NAME the scenario's name or "
                   "'sweep' for several; media/paper-tables.jsonl with --paper)")
    t.add_argument("--paper", action="store_true",
                   help="reproduce the paper's Tables II and III: every scenarios/paper/table*.yaml "
                   "(or the SCENARIOs given) at its own g and q and in auto mode")
    t.add_argument("--margin-key", default="robots.margin", metavar="KEY",
                   help="the swept field of the 'needed' tables (default robots.margin)")
    t.add_argument("--contact-bound", type=_percent, default=1.0, metavar="PCT",
                   help="the 'needed' tables give the smallest swept value whose contact rate's 95%% upper "
                   "bound is at most PCT %% (default 1)")
    t.add_argument("--summarize", metavar="RESULTS",
                   help="only write the summary files of an existing results file; run nothing")
    t.add_argument("--no-progress", action="store_true", help="no progress bar")
    t.set_defaults(func=_cmd_tune)
    t.error = _one_line_error(t)  # bad options: one line, exit 2, like bad files
    return t


def _seconds_at_least_0(value: str) -> float:
    try:
        v = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number of seconds >= 0, got {value[:80]!r}") from None
    if not math.isfinite(v) or v < 0:
        raise argparse.ArgumentTypeError(f"must be a finite number of seconds >= 0, got {value[:80]}")
    return v


def _percent(value: str) -> float:
    try:
        v = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a percentage in (0, 100), got {value[:80]!r}") from None
    if not 0 < v < 100:
        raise argparse.ArgumentTypeError(f"must be a percentage in (0, 100), got {value[:80]}")
    return v


def _one_line_error(parser: argparse.ArgumentParser) -> Callable[[str], None]:
    def error(message: str) -> None:
        parser.exit(2, f"{parser.prog}: error: {message} (see {parser.prog} --help)\n")

    return error


def _cmd_tune(args) -> int:
    from ..scenario.overrides import combinations, parse_set
    from .cluster import ClusterLostError
    from .driver import sweep
    from .spec import PAPER_DIR, TuneError, grid, paper_grid, read_variants

    if args.summarize is not None:
        return _cmd_summarize(args)
    if args.paper:
        if args.g or args.q or args.auto:
            raise TuneError("--paper: runs each scenario at the paper's own g and q and in auto mode; "
                            "drop --g, --q and --auto")
        files = args.scenarios or sorted(str(p) for p in PAPER_DIR.glob("table*.yaml"))
        if not files:
            raise TuneError(f"{PAPER_DIR}: no table*.yaml scenarios; give the SCENARIO files")
    else:
        files = args.scenarios
        if not files:
            raise TuneError("SCENARIO: give at least one scenario file (or --paper, or --summarize FILE)")
    overrides = [parse_set(text) for text in args.sets]
    size = len(files) * args.seeds * math.prod(len(x) for x in (args.g or [1], args.q or [1]))
    size *= math.prod(len(o.values) for o in overrides)
    if size > _MAX_GRID:
        raise TuneError(f"{'--set' if overrides else '--seeds'}: the grid has {size} runs; at most "
                        f"{_MAX_GRID} in one sweep")
    combos = combinations(overrides)
    variants = read_variants(files, combos)
    names = list(dict.fromkeys(sc.name for sc, _ in variants))
    if args.paper:
        default = Path("media") / "paper-tables.jsonl"
    else:
        default = Path("media") / f"{names[0] if len(names) == 1 else 'sweep'}-tune.jsonl"
    out = _results_path(args.output, default)
    seeds = range(args.seed_start, args.seed_start + args.seeds)
    if args.paper:
        specs = paper_grid(variants, seeds=seeds, time_limit=args.time_limit, simulate=args.simulate)
    else:
        specs = grid(variants, g=args.g, q=args.q, auto=args.auto, seeds=seeds,
                     time_limit=args.time_limit, simulate=args.simulate)
    try:
        result = sweep(specs, out, workers=args.workers, scheduler=args.scheduler,
                       progress=False if args.no_progress else None, log=sys.stderr, allowance=args.allowance)
    except ClusterLostError as exc:
        print(f"swarmform tune: error: {exc}", file=sys.stderr)
        return EXIT_CLUSTER_LOST
    print(f"swarmform tune: {result.computed} runs computed ({result.no_plan} without a plan, "
          f"{result.raised} raised, {result.timed_out} timed out, {result.worker_died} lost with their worker), "
          f"{result.skipped} were already in {out}")
    _report(out, paper_only=args.paper, key=args.margin_key, bound=args.contact_bound / 100)
    if result.not_done:
        reasons = Counter(reason for _, reason in result.not_done)
        for reason, n in reasons.most_common(3):
            print(f"swarmform tune: {n} runs not done: {reason}", file=sys.stderr)
        print(f"swarmform tune: rerun the same command to compute the {len(result.not_done)} missing runs",
              file=sys.stderr)
        return EXIT_INCOMPLETE
    return EXIT_OK


def _cmd_summarize(args) -> int:
    from .results import check_output
    from .spec import TuneError

    extra = [name for name, given in (("SCENARIO", args.scenarios), ("--g", args.g), ("--q", args.q),
                                      ("--auto", args.auto), ("--paper", args.paper), ("--set", args.sets),
                                      ("--simulate", args.simulate), ("--scheduler", args.scheduler),
                                      ("--workers", args.workers is not None),
                                      ("--time-limit", args.time_limit is not None),
                                      ("--allowance", args.allowance is not None),
                                      ("--output", args.output)) if given]
    if extra:
        raise TuneError(f"--summarize: runs nothing, so {extra[0]} does not apply")
    path = Path(args.summarize)
    if not path.is_file():
        raise TuneError(f"{path}: no such results file")
    try:
        check_output(path)
    except TuneError as exc:
        raise TuneError(str(exc).replace("--output: ", "--summarize: ", 1)) from None
    _report(path, paper_only=False, key=args.margin_key, bound=args.contact_bound / 100)
    return EXIT_OK


def _results_path(output: str | None, default: Path) -> Path:
    from .results import check_output
    from .spec import TuneError

    path = Path(output) if output else default
    if path.suffix in (".md", ".png", ".html"):
        raise TuneError(f"--output: {path}: the results file may not end in {path.suffix}; "
                        "the summary is written beside it with that suffix")
    return check_output(path)


def _report(results_path: Path, *, paper_only: bool, key: str, bound: float) -> None:
    """Write the summary files, print the Markdown (only the paper's tables for --paper)."""
    from .report import write_summary
    from .results import read_results
    from .spec import TuneError
    from .summary import paper_table

    rows = read_results(results_path)
    if not rows:
        raise TuneError(f"{results_path}: holds no result rows")
    text, written = write_summary(results_path, rows, key=key, bound=bound)
    shown = paper_table(rows) if paper_only else None
    print()
    print(shown if shown else text.rstrip())
    print()
    for p in written:
        print(f"wrote {p}")
