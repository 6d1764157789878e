"""Regression runs: ``swarmform check`` runs scenarios without video and says PASS or FAIL.

:func:`run_check` runs each scenario (a folder stands for every ``*.yaml``
in it, sorted) with :func:`sim.runner.run_scenario`, ``render=False``, into
a scratch folder (or ``out_dir``), and returns one :class:`CheckCase` per
scenario.  A case passes when its run passes (exit 0: plan found, valid,
executed with zero contacts, every robot on a target) and, with a baseline
folder, when its report agrees with the report stored there as
``BASELINE/NAME.json`` within :data:`TOLERANCES`:

* ``ok`` (the verdict) and ``sim.contacts`` (the number of contacts): equal;
* ``plan.makespan_s`` and ``plan.path_length``: within 5 % relative
  (``|new - old| <= 0.05 * |old|``);
* ``plan.min_clearance``: within 1e-3 absolute (workspace units).

A difference fails the case and names the field, the old and the new value.
``update=True`` writes the new reports as the baseline instead (each file
atomically) and compares nothing.  :func:`write_junit` writes the cases as
JUnit XML (``testsuites/testsuite/testcase/failure``), what CI systems read.

The output folders are checked first; then, before the first run, the
paths, the scenarios (with the ``--set`` overrides), the plan files (as
files) and the baseline files; a wrong one raises
:class:`sim.errors.InputError` (or the scenario's or plan file's own error)
naming the file, the field and the reason.  What only a run can see (a plan
that does not fit its scenario, a run over the physics budget) raises the
same errors when that scenario runs, as ``swarmform run`` would.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

from .errors import InputError

__all__ = ["TOLERANCES", "CheckCase", "add_check_parser", "cmd_check", "compare_reports", "run_check",
           "scenario_files", "write_junit"]

TOLERANCES: dict[str, tuple[str, float]] = {
    "ok": ("equal", 0.0),
    "sim.contacts": ("equal", 0.0),
    "plan.makespan_s": ("relative", 0.05),
    "plan.path_length": ("relative", 0.05),
    "plan.min_clearance": ("absolute", 1e-3),
}
"""Field of the run report -> (kind, tolerance) a baseline comparison allows."""

_BASELINE_MAX_BYTES = 16 * 1024 * 1024
_DROPPED = ("page", "media")  # paths into the scratch folder: meaningless in a baseline


class CheckCase:
    """One scenario's check: whether it passed and why (``line``), with its report, its
    baseline differences and its wall time [s].  (A plain class: ``swarmform --help``
    imports this module, and ``dataclasses`` is slow to import.)"""

    def __init__(self, name: str, path: Path, ok: bool, line: str, report: dict,
                 differences: list[str] | None = None, time_s: float = 0.0):
        self.name, self.path, self.ok, self.line, self.report = name, Path(path), ok, line, report
        self.differences = list(differences or [])
        self.time_s = time_s

    def __repr__(self) -> str:
        return f"CheckCase({self.name!r}, ok={self.ok}, {self.message!r})"

    @property
    def message(self) -> str:
        """The verdict line, then the baseline differences."""
        if not self.differences:
            return self.line
        return f"{self.line}; baseline: " + "; ".join(self.differences)


def scenario_files(paths) -> list[Path]:
    """The scenario files named by ``paths``: files as given, folders as their ``*.yaml``, sorted."""
    files: list[Path] = []
    for raw in paths:
        p = Path(raw)
        if p.is_dir():
            found = sorted(q for q in p.glob("*.yaml") if q.is_file())
            if not found:
                raise InputError(f"{p}: folder: holds no *.yaml scenario files")
            files.extend(found)
        elif p.is_file():
            files.append(p)
        else:
            raise InputError(f"{p}: file: no such file")
    return files


def _get(report: dict, dotted: str):
    v: Any = report
    for key in dotted.split("."):
        if not isinstance(v, dict):
            return None
        v = v.get(key)
    return v


def _fmt(v) -> str:
    import json

    return f"{v:.6g}" if isinstance(v, float) else json.dumps(v)


def compare_reports(old: dict, new: dict) -> list[str]:
    """The fields of :data:`TOLERANCES` on which ``new`` departs from ``old``, each said with both values."""
    out = []
    for key, (kind, tol) in TOLERANCES.items():
        a, b = _get(old, key), _get(new, key)
        if kind == "equal" or not _is_number(a) or not _is_number(b):
            same = a == b
            why = "" if kind == "equal" else " (one is missing)"
        elif kind == "relative":
            same = abs(b - a) <= tol * abs(a)
            why = f" (more than {tol:.0%} apart)"
        else:
            same = abs(b - a) <= tol
            why = f" (more than {tol:g} apart)"
        if not same:
            out.append(f"{key} was {_fmt(a)}, now {_fmt(b)}{why}")
    return out


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _read_baseline(path: Path) -> dict:
    import json

    try:
        size = path.stat().st_size
        if size > _BASELINE_MAX_BYTES:
            raise InputError(f"{path}: file: is {size} bytes, more than a run report's {_BASELINE_MAX_BYTES}")
        d = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: file: cannot be read ({exc.__class__.__name__})") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: line {exc.lineno}: is not JSON ({exc.msg})") from None
    if not isinstance(d, dict):
        raise InputError(f"{path}: file: must hold one JSON object (a run report), got {type(d).__name__}")
    return d


def _write_baseline(path: Path, report: dict) -> None:
    import json

    from .output.media import atomic_path

    kept = {k: v for k, v in report.items() if k not in _DROPPED}
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(kept, indent=2, allow_nan=False) + "\n", encoding="utf-8")


def _match_plans(plans, scenarios: dict[str, Path]) -> dict[str, Path]:
    """Plan file for each scenario name: the file's ``scenario`` key names it, or the only scenario."""
    from planner.plan import note_ignored, read_plan_file

    out: dict[str, Path] = {}
    for raw in plans or ():
        path = Path(raw)
        _plan, extra = read_plan_file(path)
        note_ignored(path, extra)
        name = extra.get("scenario")
        if name is None:
            if len(scenarios) != 1:
                raise InputError(f"{path}: scenario: the plan file names no scenario; with several "
                                 f"scenarios each plan file needs its \"scenario\" key")
            name = next(iter(scenarios))
        if name not in scenarios:
            raise InputError(f"{path}: scenario: {_fmt(name)} is not one of the scenarios checked")
        if name in out:
            raise InputError(f"{path}: scenario: {out[name]} is already the plan of {name}")
        out[name] = path
    return out


def run_check(paths, *, baseline=None, update: bool = False, overrides: dict | None = None,
              seed: int | None = None, plans=(), out_dir=None, out=sys.stdout) -> list[CheckCase]:
    """Run every scenario of ``paths`` without video; one :class:`CheckCase` each (see the module docstring).

    ``out`` gets one line per scenario (name, PASS or FAIL, the verdict)
    and a summary; ``None`` prints nothing.
    """
    import tempfile

    from .output.files import check_out_dir
    from .scenario.reader import read_scenario

    if out_dir is not None:
        check_out_dir(out_dir)
    if baseline is not None and update:
        check_out_dir(baseline, "--baseline")
    files = scenario_files(paths)
    names: dict[str, Path] = {}
    for f in files:  # every scenario read (and checked) before the first run
        name = read_scenario(f, overrides=overrides).name
        if name in names:
            raise InputError(f"{f}: name: {name!r} is also the name of {names[name]}; "
                             f"the scenarios checked together need names of their own")
        names[name] = f
    plan_of = _match_plans(plans, names)
    base = None
    old: dict[str, dict] = {}
    if baseline is not None:
        base = Path(baseline)
        if update:  # made before the first run, so the folder exists while the reports are written
            base.mkdir(parents=True, exist_ok=True)
        else:
            if not base.is_dir():
                raise InputError(f"{base}: --baseline: is not a folder (make one with --update-baseline)")
            old = {n: _read_baseline(base / f"{n}.json") for n in names if (base / f"{n}.json").is_file()}
    with tempfile.TemporaryDirectory(prefix="swarmform-check-") as scratch:
        cases = [_run_one(name, f, Path(out_dir or scratch), seed, overrides, plan_of.get(name), base,
                          old, update, out) for name, f in names.items()]
    if out is not None:
        bad = sum(not c.ok for c in cases)
        total = sum(c.time_s for c in cases)
        print(f"{len(cases)} scenario{'s' * (len(cases) != 1)}: {len(cases) - bad} passed, {bad} failed "
              f"({total:.1f} s)", file=out)
    return cases


def _run_one(name, path, out_dir, seed, overrides, plan, base, old, update, out) -> CheckCase:
    import time

    from .output.verdict import verdict
    from .runner import run_scenario

    t0 = time.perf_counter()
    result = run_scenario(path, seed=seed, out_dir=out_dir, render=False, plan_path=plan, progress=False,
                          out=None, overrides=overrides or None)
    ok, line = verdict(result.report)
    ok = ok and result.exit_code == 0
    case = CheckCase(name, Path(path), ok, line, result.report, time_s=time.perf_counter() - t0)
    if base is not None and update:
        _write_baseline(base / f"{name}.json", result.report)
    elif base is not None:
        if name in old:
            case.differences = compare_reports(old[name], result.report)
        else:
            case.differences = [f"no baseline {base / (name + '.json')} (write it with --update-baseline)"]
        case.ok = case.ok and not case.differences
    if out is not None:
        print(f"{name:<40} {'PASS' if case.ok else 'FAIL'}  {case.message}  ({case.time_s:.1f} s)",
              file=out, flush=True)
    return case


def write_junit(path, cases: list[CheckCase], suite: str = "swarmform check") -> Path:
    """Write ``cases`` as JUnit XML to ``path`` (atomically): a failed case has a ``failure``
    whose ``message`` is its verdict line (and baseline differences)."""
    import json
    import xml.etree.ElementTree as ET

    from .output.media import atomic_path

    root = ET.Element("testsuites")
    failures = sum(not c.ok for c in cases)
    total = f"{sum(c.time_s for c in cases):.3f}"
    ts = ET.SubElement(root, "testsuite", name=suite, tests=str(len(cases)), failures=str(failures),
                       errors="0", skipped="0", time=total)
    root.set("tests", str(len(cases)))
    root.set("failures", str(failures))
    for c in cases:
        tc = ET.SubElement(ts, "testcase", classname=f"swarmform.{c.path.parent.name or 'scenarios'}",
                           name=c.name, file=str(c.path), time=f"{c.time_s:.3f}")
        if not c.ok:
            kind = "baseline" if c.differences and c.line.startswith("ok") else "run"
            fail = ET.SubElement(tc, "failure", message=c.message, type=kind)
            fail.text = json.dumps({"plan": c.report.get("plan"), "first_contact":
                                    (c.report.get("sim") or {}).get("first_contact")}, indent=2, default=str)
        ET.SubElement(tc, "system-out").text = c.line
    ET.indent(root)
    path = Path(path)
    with atomic_path(path) as tmp:
        ET.ElementTree(root).write(tmp, encoding="utf-8", xml_declaration=True)
    return path


# ----------------------------------------------------------------------------
# the command (registered by sim.cli; nothing heavy is imported until it runs)

_CHECK_DESCRIPTION = """\
Run scenarios as regression tests, without video: one line per scenario
(name, PASS or FAIL, the verdict), exit 0 when all pass, 1 when one fails,
2 on wrong input.  A folder stands for every *.yaml in it, sorted.

With --baseline DIR each report is also compared with DIR/NAME.json, a
report stored earlier (--update-baseline writes them); the case fails when
a field departs by more than its tolerance, and the line names the field,
the old and the new value:
  ok (the verdict), sim.contacts        equal
  plan.makespan_s, plan.path_length     5 % relative
  plan.min_clearance                    1e-3 absolute [workspace units]
"""


def add_check_parser(sub, parents=()):
    """Register ``swarmform check`` on the CLI's subparsers."""
    import argparse

    c = sub.add_parser("check", help="run scenarios as regression tests (no video): PASS/FAIL lines, "
                       "JUnit XML, baseline comparison", description=_CHECK_DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter, parents=list(parents))
    c.add_argument("scenarios", nargs="+", metavar="SCENARIO_OR_DIR",
                   help="scenario YAML files, or folders of them (every *.yaml, sorted)")
    c.add_argument("--junit", metavar="FILE", help="also write the results as JUnit XML to FILE")
    c.add_argument("--baseline", metavar="DIR", help="compare each report with DIR/NAME.json (tolerances above)")
    c.add_argument("--update-baseline", action="store_true",
                   help="write the reports to the --baseline folder instead of comparing")
    c.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="set a field of every scenario (dotted path, YAML scalar), e.g. robots.margin=0.2; "
                   "repeatable")
    c.add_argument("--seed", type=_seed, help="override every scenario's seed")
    c.add_argument("--plan", action="append", default=[], metavar="PLAN.json",
                   help="execute this plan file as it is for the scenario its \"scenario\" key names "
                   "(or the only scenario given); repeatable")
    c.add_argument("--out", metavar="DIR", help="keep the run reports in DIR (default: a scratch folder)")
    c.set_defaults(func=cmd_check)
    return c


def _seed(text: str) -> int:
    from .argtypes import int_in

    return int_in(0, 2**63 - 1)(text)


def cmd_check(args) -> int:
    """``swarmform check``: exit 0 all pass, 1 one fails (2 and 3 raised as errors to the CLI)."""
    from .output.files import check_out_file
    from .scenario.overrides import combinations, parse_set

    if args.update_baseline and not args.baseline:
        raise InputError("--update-baseline: needs --baseline DIR (the folder to write)")
    if args.junit:
        check_out_file(args.junit, "--junit")
    overrides = combinations([parse_set(text, many=False) for text in args.set])[0]
    cases = run_check(args.scenarios, baseline=args.baseline, update=args.update_baseline,
                      overrides=overrides, seed=args.seed, plans=args.plan, out_dir=args.out)
    if args.update_baseline:
        print(f"wrote {len(cases)} baseline report{'s' * (len(cases) != 1)} to {args.baseline}")
    if args.junit:
        write_junit(args.junit, cases)
        print(f"wrote {args.junit}")
    return 0 if all(c.ok for c in cases) else 1
