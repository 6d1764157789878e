"""Mutation testing of the modules that carry the verdict, one module at a time.

    python tests/mutation/mutate.py validate            # mutate, test, summarise, clean up
    python tests/mutation/mutate.py validate --keep     # keep mutants/ to inspect survivors
    python tests/mutation/mutate.py validate --show     # summarise a kept run, with diffs
    python tests/mutation/mutate.py --list              # the modules and their tests

It drives mutmut 3 (``pip install -e '.[mutation]'``) from the repository root. mutmut
copies ``planner/`` and ``sim/`` into ``mutants/``, rewrites one module so that every
mutant can be switched on at run time, records which tests call which function, and then
runs, for each mutant, only the tests that call the mutated function. Here each module is
mutated alone, against only the test files listed for it below, so one module takes
minutes (modules too slow for that are mutated in a scope of functions, see SCOPE). The
surviving mutants, with their diffs, go to ``mutation-report/MODULE.txt``. One worker
process: run it under a memory limit, e.g.

    prlimit --as=4000000000 timeout 3h python tests/mutation/mutate.py geometry

Exit status: 0 when at least 95 % of the mutants that are not listed as equivalent in
``tests/mutation/EQUIVALENT.md`` are killed (a timeout counts as killed), 1 otherwise.
"""

from __future__ import annotations

import argparse
import dataclasses
import fnmatch
import json
import os
import shutil
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
EQUIVALENT = HERE / "EQUIVALENT.md"
GOAL = 0.95
REPORTS = ROOT / "mutation-report"  # the survivors of the last run of each module

# module -> (file to mutate, test files that pin its behaviour).  The hypothesis fuzz tests
# of the loaders (tests/sim/test_input_fuzz.py) are left out: a minute a run, and every
# mutant of the readers would run them.
MODULES: dict[str, tuple[str, list[str]]] = {
    "validate": (
        "planner/validate.py",
        [
            "tests/planner/test_validate.py",
            "tests/planner/test_margin_extra.py",
            "tests/planner/test_validate_pins.py",
            # 3 s a run, and every mutant of min_clearance would run it
            "--deselect=tests/planner/test_validate.py::test_min_clearance_matches_brute_force",
        ],
    ),
    "geometry": (
        "planner/geometry.py",
        [
            "tests/planner/test_geometry_pins.py",
            "tests/planner/test_geometry_fast.py",
            "--deselect=tests/planner/test_geometry_fast.py::test_indexed_kernels_match_the_dense_ones_in_clutter",
        ],
    ),
    "contacts": (
        "sim/execute/contacts.py",
        [
            "tests/sim/test_contacts.py",
            "tests/sim/test_contacts_pins.py",
            "tests/sim/test_verdict.py",
            "--deselect=tests/sim/test_verdict.py::test_a_plan_below_the_margin_fails_the_run_though_nothing_touches",
        ],
    ),
    "monitor": (
        "sim/execute/monitor.py",
        [
            "tests/sim/test_contacts.py",
            "tests/sim/test_contacts_pins.py",
            "tests/sim/test_verdict.py",
            "--deselect=tests/sim/test_verdict.py::test_a_plan_below_the_margin_fails_the_run_though_nothing_touches",
        ],
    ),
    "physics": (
        "sim/execute/physics.py",
        [
            "tests/sim/test_execute.py",
            "tests/sim/test_verdict.py",
            "tests/sim/test_control.py",
            "tests/sim/test_realism.py",
            "tests/sim/test_physics_pins.py",
            # two subprocesses under other hash seeds, 3 s a run; a 5 s run of a
            # plan below the margin (the pins cover what it shows here)
            "--deselect=tests/sim/test_execute.py::test_deterministic_across_hash_seeds",
            "--deselect=tests/sim/test_verdict.py::test_a_plan_below_the_margin_fails_the_run_though_nothing_touches",
        ],
    ),
    "outcome": (
        "sim/execute/outcome.py",
        [
            "tests/sim/test_execute.py",
            "tests/sim/test_verdict.py",
            "tests/sim/test_physics_pins.py",
            "--deselect=tests/sim/test_execute.py::test_deterministic_across_hash_seeds",
            "--deselect=tests/sim/test_verdict.py::test_a_plan_below_the_margin_fails_the_run_though_nothing_touches",
        ],
    ),
    "fields": (
        "sim/scenario/fields.py",
        [
            "tests/sim/test_scenario_pins.py",
            "tests/sim/test_input_contract.py",
        ],
    ),
    "scenario": (
        "sim/scenario/reader.py",
        [
            "tests/sim/test_scenario_pins.py",
            "tests/sim/test_input_contract.py",
        ],
    ),
    "inputfile": (
        "planner/inputfile.py",
        [
            "tests/sim/test_input_contract.py",
            "tests/sim/test_inputfile_pins.py",
        ],
    ),
    "yamlfile": (
        "sim/scenario/yamlfile.py",
        [
            "tests/sim/test_input_contract.py",
            "tests/sim/test_yamlfile_pins.py",
        ],
    ),
}

# Functions mutated, where a module is too slow to mutate whole on one core: the rest of
# the module's mutants are generated but not run, and the summary says how many that is.
SCOPE: dict[str, list[str]] = {
    # the ideal loop, the input checks, target matching and the report; not the
    # realistic loop (_execute_real) nor the replanning world (mutmut's names: x_ + the
    # function's name, or xǁClassǁmethod; a pattern without the __mutmut_ suffix also
    # brings in that function's tests for mutmut's first, clean run)
    "physics": ["x__check*", "x__execute__mutmut_*", "x_execute*"],
    # the kernels of the exact validator and the contact monitor; not the planner's
    # pruned tests (segments_clear, points_clear, greedy_separated and their indexes)
    "geometry": ["x_point_segment_distance*", "x__orient*", "x__crossing*", "x_segment_segment_distance*",
                 "x_closest_approach*", "x_points_in_polygon*", "x__fold_min*", "xǁEnvironmentǁwall_clearance*",
                 "xǁEnvironmentǁpoint_clearance*", "xǁEnvironmentǁsegment_clearance*", "xǁEnvironmentǁ_inside*"],
    # the file's first reading (the field checks are the "fields" module, whole)
    "scenario": ["x_read_scenario*"],
}


def _patterns(module: str) -> list[str]:
    """mutmut name patterns of a module's scope, or [] for the whole module."""
    prefix = MODULES[module][0].removesuffix(".py").replace("/", ".") + "."
    return [prefix + p for p in SCOPE.get(module, [])]


_STATUS = {1: "killed", 3: "killed", 0: "survived", 5: "no tests", 33: "no tests", 36: "timeout",
           24: "timeout", -24: "timeout", 152: "timeout", 255: "timeout", None: "not checked"}


def equivalent_ids(module_file: str) -> set[str]:
    """Mutant names listed in EQUIVALENT.md for one file (rows ``| file | name | why |``)."""
    if not EQUIVALENT.exists():
        return set()
    names = set()
    for line in EQUIVALENT.read_text().splitlines():
        cells = [c.strip().strip("`") for c in line.strip().strip("|").split("|")]
        if len(cells) >= 3 and cells[0] == module_file:
            names.add(cells[1])
    return names


def summarise(module: str, show: bool, out=None) -> dict:
    module_file, _ = MODULES[module]
    meta = ROOT / "mutants" / (module_file + ".meta")
    if not meta.exists():
        raise SystemExit(f"no results for {module_file}: run it first (with --keep to inspect)")
    codes = json.loads(meta.read_text())["exit_code_by_key"]
    patterns = _patterns(module)
    outside = 0
    if patterns:
        inside = {k: v for k, v in codes.items() if any(fnmatch.fnmatch(k, p) for p in patterns)}
        outside = len(codes) - len(inside)
        codes = inside
    equivalent = equivalent_ids(module_file)
    unknown = sorted(equivalent - set(codes))
    counts = {"killed": 0, "timeout": 0, "survived": 0, "equivalent": 0, "no tests": 0, "other": 0}
    survivors = []
    for name, code in sorted(codes.items()):
        status = _STATUS.get(code, "other")
        if status in ("survived", "no tests") and name in equivalent:
            status = "equivalent"
        elif status in ("survived", "no tests"):
            survivors.append(name)
        counts[status if status in counts else "other"] += 1
    counts["total"] = len(codes)
    counts["out_of_scope"] = outside
    live = counts["total"] - counts["equivalent"]
    counts["kill_rate"] = (counts["killed"] + counts["timeout"]) / live if live else 1.0
    line = (f"{module_file}: {counts['total']} mutants, {counts['killed']} killed, "
            f"{counts['timeout']} timed out, {counts['survived']} survived, "
            f"{counts['no tests']} not reached by any test, {counts['equivalent']} equivalent, "
            f"{counts['other']} other; kill rate {100 * counts['kill_rate']:.1f} % of non-equivalent"
            + (f" ({outside} mutants outside the scope {', '.join(SCOPE[module])} not run)" if outside else ""))
    print(line)
    if out is not None:
        out.write(line + "\n\n" + "".join(f"# {name}\n{_diff(name)}\n" for name in survivors))
    killed_listed = sorted(n for n in equivalent & set(codes) if _STATUS.get(codes[n]) in ("killed", "timeout"))
    if killed_listed:
        print(f"  listed in EQUIVALENT.md but killed: {', '.join(killed_listed)}")
    if unknown:
        print(f"  EQUIVALENT.md names mutants that were not generated: {', '.join(unknown)}")
    for name in survivors:
        print(f"  survived: {name}")
        if show:
            print(_diff(name))
    return counts


def _diff(name: str) -> str:
    from mutmut.mutation.diff_apply import find_mutant, get_diff_for_mutant

    return get_diff_for_mutant(name, path=find_mutant(name).path)


def run(module: str, keep: bool, names: list[str]) -> dict:
    module_file, tests = MODULES[module]
    tests = [t for t in tests if t.startswith("-") or (ROOT / t).exists()]
    os.chdir(ROOT)
    fresh = not names
    names = names or _patterns(module)
    if fresh and (ROOT / "mutants").exists():
        shutil.rmtree(ROOT / "mutants")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

    from mutmut import configuration
    from mutmut.__main__ import cli

    base = configuration._load_config()
    # mutmut copies tests/ following symbolic links; the bad-input corpus holds a link to
    # /dev/zero, so copy tests/ here with the links kept as links, and let mutmut skip it.
    shutil.rmtree(ROOT / "mutants" / "tests", ignore_errors=True)
    shutil.copytree(ROOT / "tests", ROOT / "mutants" / "tests", symlinks=True,
                    ignore=shutil.ignore_patterns("__pycache__", ".hypothesis"))
    configuration._config = dataclasses.replace(
        base,
        also_copy=[p for p in base.also_copy if p.parts[:1] != ("tests",)],
        only_mutate=[module_file],
        pytest_add_cli_args_test_selection=tests,
    )
    start = time.monotonic()
    try:
        cli(["run", "--max-children", "1", *names], standalone_mode=False)
    except SystemExit as exc:  # mutmut exits 1 when the clean run fails
        if exc.code:
            raise
    wall = time.monotonic() - start
    REPORTS.mkdir(exist_ok=True)
    with (REPORTS / f"{module}.txt").open("w") as out:
        counts = summarise(module, show=False, out=out)
    print(f"  surviving mutants with their diffs: {(REPORTS / f'{module}.txt').relative_to(ROOT)}")
    counts["wall_s"] = round(wall)
    print(f"  wall time {wall / 60:.1f} min")
    if not keep:
        shutil.rmtree(ROOT / "mutants", ignore_errors=True)
    return counts


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("module", nargs="?", choices=sorted(MODULES))
    parser.add_argument("mutants", nargs="*", help="re-run only these mutants of a kept run")
    parser.add_argument("--keep", action="store_true", help="keep mutants/ for inspection")
    parser.add_argument("--show", action="store_true", help="summarise a kept run, with diffs")
    parser.add_argument("--list", action="store_true", help="list the modules and their tests")
    parser.add_argument("--json", type=Path, help="append the counts as one JSON line here")
    args = parser.parse_args(argv)
    if args.list or not args.module:
        for name, (path, tests) in MODULES.items():
            print(f"{name:10} {path:22} {' '.join(tests)}")
        return 0
    if args.show:
        os.chdir(ROOT)
        counts = summarise(args.module, show=True)
    else:
        counts = run(args.module, keep=args.keep or bool(args.mutants), names=args.mutants)
    if args.json:
        with args.json.open("a") as f:
            f.write(json.dumps({"module": args.module, **counts}) + "\n")
    return 0 if counts["kill_rate"] >= GOAL else 1


if __name__ == "__main__":
    sys.exit(main())
