"""The ``swarmform`` command line.

Exit codes: 0 success; 1 no plan within the limits, or the physics run saw
a contact or missed a target (the report is still written); 2 bad input
(one line naming the file, the field and the reason; no traceback).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["main"]

EXIT_OK, EXIT_FAIL, EXIT_INPUT = 0, 1, 2


class InputError(Exception):
    """Bad command-line input; ``str()`` is the one-line message."""


def _seed_arg(value: str) -> int:
    try:
        v = int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {value!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {v}")
    return v


def _cmd_formations(args) -> int:
    from planner.formations import DEFAULT_COUNTS

    print("formation  default count (paper Table I)")
    for name, count in DEFAULT_COUNTS.items():
        print(f"{name:<10} {count if count is not None else 'needs robots.count'}")
    return EXIT_OK


def _load(path: str, seed: int | None):
    """Read a scenario and build its problem with the run's one generator."""
    import numpy as np

    from .scenario import build_problem, read_scenario

    scenario = read_scenario(path)
    seed = scenario.seed if seed is None else seed
    rng = np.random.default_rng(seed)
    problem = build_problem(scenario, rng)
    return scenario, seed, rng, problem


def _cmd_show(args) -> int:
    from .media import write_png
    from .render import draw_scenario

    scenario, seed, _rng, problem = _load(args.scenario, args.seed)
    out = Path(args.output) if args.output else Path("media") / f"{scenario.name}-scenario.png"
    title = f"{scenario.name}  seed {seed}"
    image = draw_scenario(problem, size=args.size, title=title)
    write_png(out, image)
    print(f"wrote {out}  ({scenario.start.describe()} -> {scenario.target.describe()}, m={problem.m})")
    return EXIT_OK


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="swarmform",
        description="Switch a swarm of disc robots between formations: plan with UPUMP, "
        "check the plan exactly, execute it in pymunk and render it.",
    )
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    f = sub.add_parser("formations", help="list the formations and their default robot counts")
    f.set_defaults(func=_cmd_formations)

    s = sub.add_parser("show", help="draw a scenario (start hollow, target filled) to a PNG")
    s.add_argument("scenario", help="scenario YAML file")
    s.add_argument("--seed", type=_seed_arg, help="override the scenario's seed")
    s.add_argument("-o", "--output", help="PNG file (default media/NAME-scenario.png)")
    s.add_argument("--size", type=int, default=480, help="picture side in pixels (default 480)")
    s.set_defaults(func=_cmd_show)
    return p


def main(argv: list[str] | None = None) -> int:
    from planner.problem import ProblemError

    from .scenario import ScenarioError

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ScenarioError, ProblemError, InputError) as exc:
        print(f"swarmform: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:
        print("swarmform: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
