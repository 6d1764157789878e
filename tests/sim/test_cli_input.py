"""The command line and wrong input: exit codes, one-line messages, bounded resources.

``tests/data/bad/`` holds the bad-input corpus: scenario files (``.yaml``)
and plan files (``.json``, made for ``tests/data/plan-base.yaml``), one or
more per class of wrong input (syntax, YAML features, file kinds and sizes,
every field's range, numbers of every odd kind, echoes of huge values,
polygons, plan files, the physics budget).  :data:`CORPUS` names, for each
file, the field its message must name and a piece of the reason.

Every file goes through ``swarmform run`` as a user would start it (a plan
file as ``run tests/data/plan-base.yaml --plan FILE``), with the address
space limited to 2 GiB (``RLIMIT_AS``, what ``prlimit --as`` sets), and must
exit 2 with exactly one line of at most 200 characters on stderr naming the
file and the field, no traceback, within seconds, and leave its output
folder empty.  In-process, scenario files must raise :class:`ScenarioError`
with that field.

Starting the interpreter and importing numpy, scipy and pygame costs more
than a second, so the corpus runs in one helper process that imports the
command once and forks a child per case (four at a time): each child sets
its address-space limit and runs ``sim.cli.main`` exactly as the
``swarmform`` console script does (``sys.exit(main())``; an uncaught
exception prints a traceback and exits 1) with its own stdout and stderr;
the helper reports each child's exit status, wall time and peak resident
memory.  A few corpus files, ``swarmform formations`` and ``swarmform show``
of a paper figure also run the installed script itself, under ``prlimit``.
All of these processes are started together by one module fixture.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from planner.formations import DEFAULT_COUNTS
from sim.cli import main
from sim.scenario import ScenarioError, build_problem, read_scenario

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data"
BAD = DATA / "bad"
PLAN_BASE = DATA / "plan-base.yaml"
FIG1 = ROOT / "scenarios" / "paper" / "fig1-line-to-phi.yaml"
FIG2 = ROOT / "scenarios" / "paper" / "fig2-random-to-C.yaml"  # random start
FIXED = ROOT / "scenarios" / "letters" / "line-to-A.yaml"  # rotations and centres given

_SCRIPT = Path(sys.executable).with_name("swarmform")
SWARMFORM = [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "sim.cli"]

ADDRESS_SPACE = 2 << 30  # bytes: every corpus run is limited to 2 GiB of address space
SECONDS = 20.0  # the longest a corpus run may take (they take well under a second here)
LINE_MAX = 200

# file -> (the field its one-line message names, a piece of the reason)
CORPUS = {
    "seed-octal.yaml": ("seed", "got string '017'"),
    "seed-sexagesimal.yaml": ("seed", "got string '1:30'"),
    "count-hex.yaml": ("robots.count", "got string '0x1F'"),
    "max-speed-underscore.yaml": ("robots.max_speed", "got string '1_000' (numbers are written in decimal only"),
    "plan-duplicate-key.json": ("radius", "is given twice"),
    "plan-origin-string.json": ("origin[0]", "got string '-12.5'"),
    "text-no-skeleton.yaml": ("target.formation.text", "'.' traces to a single point, no line to place robots"),
    "text-no-skeleton-count.yaml": ("target.formation.text", "'.' traces to a single point"),
    "text-number.yaml": ("target.formation.text", 'must be a string, got number 12345 (write it in quotes'),
    "font-nul-byte.yaml": ("target.formation.font", "holds a NUL character"),
    "scatter-too-many.yaml": ("start", "80 robots do not fit the workspace at spacing 2.1; at most"),
    "font-missing.yaml": ("target.formation.font", "no such file"),
    "target-and-targets.yaml": ("targets", "give either target (one) or targets (a chain), not both"),
    "region-outside-workspace.yaml": ("start.region", "must satisfy 0 <= x0 < x1 <= 40"),
    "text-too-long.yaml": ("target.formation.text", "must be at most 40 characters, got 42"),
    "strokes-outside-unit-box.yaml": ("target.formation.strokes[0][1]", "lies outside the unit box"),
    "budget-slow-robots.yaml": ("physics budget", "steps > 5e+07; raise robots.max_speed/max_accel"),
    "center-on-obstacle.yaml": ("target.center", "obstacle 0"),
    "center-outside-workspace.yaml": ("target.center", "outside the 40 x 40 workspace"),
    "circle-radius-huge.yaml": ("obstacles[0].circle.radius", "in (0, 40], got 1e+30"),
    "count-5000-digits.yaml": ("robots.count", "got an integer of 5000 digits"),
    "count-million.yaml": ("robots.count", "in [1, 5000], got 1000000"),
    "count-mismatch-points.yaml": ("robots.count", "is 5 but start.points has 3 points"),
    "count-one-formation.yaml": ("robots.count", "at least 2"),
    "duplicate-key.yaml": ("line 3, column 3", "duplicate key 'radius'"),
    "empty.yaml": ("file", "is empty"),
    "file-binary-garbage.yaml": ("file", "is not UTF-8 text"),
    "file-dangling-link.yaml": ("file", "no such file"),
    "file-dev-zero.yaml": ("file", "is a character device, not a regular file"),
    "file-too-big.yaml": ("file", "larger than the 2 MiB"),
    "file-utf16.yaml": ("file", "is not UTF-8 text"),
    "formation-long-string.yaml": ("start.formation", "(10000 characters)"),
    "formation-too-big.yaml": ("start", "does not fit"),
    "formation-unhashable.yaml": ("start.formation", "unknown formation"),
    "letter-count-mismatch.yaml": ("robots.count", "count mismatch"),
    "mapping-key-unhashable.yaml": ("line 1, column 3", "mapping key must be a plain value"),
    "margin-huge.yaml": ("robots.margin", "in [0, 100], got 1e+300"),
    "max-accel-huge.yaml": ("robots.max_accel", "in [0.001, 10000], got 1e+300"),
    "max-speed-inf.yaml": ("robots.max_speed", "finite number in [0.001, 1000], got inf"),
    "max-speed-tiny.yaml": ("robots.max_speed", "got 1e-300"),
    "missing-target.yaml": ("target", "is required"),
    "name-100k-characters.yaml": ("name", "(100000 characters)"),
    "name-250-characters.yaml": ("name", "(250 characters)"),
    "name-empty.yaml": ("name", "got string ''"),
    "name-path-traversal.yaml": ("name", "'../../etc/passwd'"),
    "obstacles-random-10000.yaml": ("obstacles[0].random.count", "in [1, 64], got 10000"),
    "obstacles-vertices-random.yaml": ("obstacles[1]", "brings the obstacle vertices to 552"),
    "obstacles-too-many.yaml": ("obstacles", "at most 256 obstacles, got 300"),
    "paper-time-negative.yaml": ("paper.time_s", "got -3"),
    "plan-binary-garbage.json": ("file", "is not UTF-8 text"),
    "plan-deep-nesting.json": ("file", "too deeply"),
    "plan-duration-negative.json": ("durations[0]", "in [0.001, 100000]"),
    "plan-duration-string.json": ("durations[0]", "got string"),
    "plan-duration-tiny.json": ("durations[0]", "got number 1e-300"),
    "plan-duration-zero.json": ("durations[0]", "got number 0"),
    "plan-empty.json": ("line 1", "invalid JSON"),
    "plan-huge-integer.json": ("durations[0]", "an integer of 5000 digits"),
    "plan-infinity.json": ("durations[0]", "got number inf"),
    "plan-margin-mismatch.json": ("margin", "has robots.margin 0.1"),
    "plan-max-speed-string.json": ("max_speed", "got string 'fast'"),
    "plan-missing-durations.json": ("durations", "is missing"),
    "plan-nan.json": ("waypoints[1][0][0]", "got number nan"),
    "plan-not-an-object.json": ("file", "must hold a JSON object"),
    "plan-physics-budget.json": ("physics budget", "2 robots x 1.1e+06 s: 5.28e+08 steps > 5e+07"),
    "plan-profile-unknown.json": ("profile", "'cubic'"),
    "plan-radius-mismatch.json": ("radius", "is 5 but tests/data/plan-base.yaml has robots.radius 1"),
    "plan-radius-string.json": ("radius", "got string '1'"),
    "plan-seed-string.json": ("seed", "got string '0'"),
    "plan-stats-bad.json": ("stats.found", "must be a boolean"),
    "plan-too-fast.json": ("durations[0]", "step 0 moves robot 0 at a peak speed of 4, over robots.max_speed = 2"),
    "plan-too-many-steps.json": ("durations", "at most 100000 steps"),
    "plan-too-much-acceleration.json": ("durations[0]", "peak acceleration of 4.009, over robots.max_accel = 2"),
    "plan-truncated.json": ("line 1", "invalid JSON"),
    "plan-waypoints-boolean.json": ("waypoints[1][0][1]", "got boolean True"),
    "plan-waypoints-far.json": ("waypoints[1][0][0]", "got number 1e+300"),
    "plan-waypoints-outside.json": ("waypoints[1][0]", "(45, 5) lies outside the 40 x 40 workspace"),
    "plan-waypoints-ragged.json": ("waypoints[1]", "moves 1 robot, waypoints[0] 2"),
    "plan-waypoints-strings.json": ("waypoints[0][0][0]", "got string '5'"),
    "plan-waypoints-triples.json": ("waypoints[0][0]", "got a list of 3"),
    "plan-wrong-robot-count.json": ("waypoints", "moves 1 robot but"),
    "plan-wrong-start.json": ("waypoints[0][0]", "does not start where"),
    "planner-extra-billion.yaml": ("planner.extra", "in [0, 1000], got 1000000000"),
    "planner-g-boolean.yaml": ("planner.g", "got boolean True"),
    "planner-g-zero.yaml": ("planner.g", "in [1, 100], got 0"),
    "planner-n-billion.yaml": ("planner.n", "in [2, 2000], got 1000000000"),
    "planner-q-huge.yaml": ("planner.q", "in [1, 100000], got 10000000000"),
    "planner-time-limit-inf.yaml": ("planner.time_limit", "got inf"),
    "point-inside-obstacle.yaml": ("target.points[2]", "obstacle 1"),
    "point-outside-workspace.yaml": ("start.points[1]", "the wall"),
    "points-length-mismatch.yaml": ("target.points", "has 4 robots but start.points has 3"),
    "points-overlap.yaml": ("start.points[1]", "overlaps robot 2"),
    "points-too-many.yaml": ("start.points", "got a list of 6000"),
    "polygon-10000-vertices.yaml": ("obstacles[0].polygon", "3 to 512 points [x, y], got a list of 10000"),
    "polygon-bowtie.yaml": ("obstacles[0].polygon", "is self-intersecting"),
    "polygon-collinear.yaml": ("obstacles[0].polygon", "is self-intersecting"),
    "polygon-repeated-vertex.yaml": ("obstacles[0].polygon", "repeats a vertex"),
    "polygon-self-intersecting.yaml": ("obstacles[1].polygon", "is self-intersecting"),
    "polygon-string-vertex.yaml": ("obstacles[0].polygon[1][0]", "got string '20'"),
    "polygon-vertex-outside.yaml": ("obstacles[0].polygon[2]", "outside"),
    "polygon-vertices-total.yaml": ("obstacles[2]", "brings the obstacle vertices to 540"),
    "python-tag.yaml": ("line 2, column 9", "'!!python/object/apply:os.system' is not allowed"),
    "radius-boolean.yaml": ("robots.radius", "got boolean True"),
    "radius-huge-integer.yaml": ("robots.radius", "an integer of 401 digits"),
    "radius-huge.yaml": ("robots.radius", "got 1e+300"),
    "radius-inf.yaml": ("robots.radius", "got inf"),
    "radius-nan.yaml": ("robots.radius", "got nan"),
    "radius-negative.yaml": ("robots.radius", "in [0.01, 100], got -1"),
    "radius-tiny.yaml": ("robots.radius", "got 1e-300"),
    "radius-wrong-type.yaml": ("robots.radius", "got string 'big'"),
    "render-format-unknown.yaml": ("render.formats[1]", "got string 'avi'"),
    "render-formats-three.yaml": ("render.formats", "got a list of 3"),
    "render-fps-billion-mp4.yaml": ("render.fps", "in [1, 120], got 1000000000"),
    "render-size-20000.yaml": ("render.size", "in [64, 3072], got 20000"),
    "render-size-3073.yaml": ("render.size", "in [64, 3072], got 3073"),
    "render-size-million.yaml": ("render.size", "got 1000000"),
    "render-speedup-tiny.yaml": ("render.speedup", "got 1e-09"),
    "render-video-seconds-huge.yaml": ("render.video_seconds", "got 1e+09"),
    "rotation-inf.yaml": ("start.rotation", "got inf"),
    "scale-nan.yaml": ("start.scale", "got nan"),
    "scale-too-big.yaml": ("start.scale", "in (0, 1], got 1.5"),
    "seed-date.yaml": ("seed", "got a date"),
    "seed-float.yaml": ("seed", "got number 1.5"),
    "seed-huge.yaml": ("seed", "an integer of about 41 digits"),
    "seed-negative.yaml": ("seed", "in [0, 2^63 - 1], got -4"),
    "sim-dt-coarse-for-speed.yaml": ("sim.dt", "robots.radius / (2 max_speed) = 0.005 s"),
    "sim-dt-tiny.yaml": ("sim.dt", "in [0.0001, 0.1], got 1e-09"),
    "sim-kp-inf.yaml": ("sim.kp", "got inf"),
    "sim-settle-time-huge.yaml": ("sim.settle_time", "in [0, 600], got 1e+12"),
    "sim-substeps-billion.yaml": ("sim.substeps", "in [1, 100], got 1000000000"),
    "top-level-list.yaml": ("file", "must hold a mapping"),
    "unknown-formation.yaml": ("target.formation", "got string 'B'"),
    "unknown-key-long.yaml": ("kkkkkkkkkkkkkkkkkkkkk...", "unknown key"),
    "unknown-robots-key.yaml": ("robots.colour", "unknown key"),
    "unknown-top-level-key.yaml": ("colour", "unknown key"),
    "workspace-huge.yaml": ("workspace[0]", "in [1, 1000], got 1e+09"),
    "workspace-inf.yaml": ("workspace[0]", "got inf"),
    "workspace-not-a-pair.yaml": ("workspace", "must be a pair"),
    "workspace-zero.yaml": ("workspace[0]", "got 0"),
    "yaml-alias-bomb.yaml": ("line 2, column 4", "anchors (&name) are not allowed"),
    "yaml-alias-reuse.yaml": ("line 2, column 8", "anchors (&name) are not allowed"),
    "yaml-multi-document.yaml": ("line 4, column 1", "another document"),
    "yaml-nesting-block.yaml": ("line 36, column 65", "nesting deeper than 32 levels"),
    "yaml-nesting-flow.yaml": ("line 4, column 1008", "nesting depth"),
    "yaml-nul-character.yaml": ("line 4, column 8", "U+0000"),
    "yaml-syntax-error.yaml": ("line 2, column 7", "invalid YAML"),
    "yaml-tab-indent.yaml": ("line 3, column 1", "invalid YAML"),
    "yaml-tag-binary.yaml": ("line 2, column 7", "'!!binary' is not allowed"),
    "yaml-tag-custom.yaml": ("line 4, column 9", "'!robot' is not allowed"),
    "yaml-tag-timestamp-explicit.yaml": ("line 2, column 7", "'!!timestamp' is not allowed"),
    # map: and .scen files (the files they point at are in tests/data/maps/bad/)
    "map-and-workspace.yaml": ("workspace", "is set by map"),
    "map-binary-garbage.yaml": ("map.file", "garbage.map: is not UTF-8 text"),
    "map-cell-missing.yaml": ("map.cell", "is required"),
    "map-cells-5000x5000.yaml": ("map.file", "height must be in [1, 4096] cells, got 5000"),
    "map-height-100000000.yaml": ("map.file", "height must be in [1, 4096] cells, got 100000000"),
    "map-image-5000x5000.yaml": ("map.file", "5000 x 5000 pixels is larger than 4096 x 4096"),
    "map-image-20000x20000.yaml": ("map.file", "huge-20000x20000.png: its header declares more pixels than 4096 x 4096"),
    "map-image-garbage.yaml": ("map.file", "not-an-image.png: is not a readable PNG or PGM image (cannot identify image file)"),
    "map-image-jpeg-as-png.yaml": ("map.file", "jpeg-named-png.png: is a JPEG image, not a PNG or PGM (whatever its suffix)"),
    "map-ros-missing-image.yaml": ("map.file", "image nothere.pgm: no such file"),
    "map-row-too-long.yaml": ("map.file", "row 2 (line 6): has 6 cells, but its header declares width 4"),
    "map-rows-fewer.yaml": ("map.file", "has 2 map rows, but its header declares height 4"),
    "map-too-many-pieces.yaml": ("map.file", "gives more than 4096 obstacle rectangles"),
    "map-truncated.yaml": ("map.file", "has 3 map rows, but its header declares height 4"),
    "map-unknown-cell.yaml": ("map.file", "row 2, column 3: unknown cell 'x'"),
    "map-unknown-format.yaml": ("map.file", "unknown map format '.md'"),
    "map-wrong-header.yaml": ("map.file", "line 2: expected 'height'"),
    "scen-bad-line.yaml": ("start.scen", "bad-line.scen line 3: start_y must be a whole number"),
    "scen-count-not-robots-count.yaml": ("robots.count", "is 3 but start.count takes 2 agents"),
    "scen-count-too-large.yaml": ("start.count", "holds 3 agents, fewer than the count 500"),
    "scen-without-map.yaml": ("start.scen", "needs a map"),
    "scen-wrong-map-size.yaml": ("start.scen", "is for a 32 x 32 map, but the map is 4 x 4"),
}

# Files the physics budget refuses: they are valid until the plan is known,
# so their run prints its first line on stdout before the refusal.
AFTER_PLANNING = {"budget-slow-robots.yaml", "plan-physics-budget.json"}

BAD_FILES = sorted(BAD.iterdir())


def _argv(path: Path, out_dir: Path) -> list[str]:
    rel = str(path.relative_to(ROOT))
    if path.suffix == ".json":
        return ["run", str(PLAN_BASE.relative_to(ROOT)), "--plan", rel, "--out", str(out_dir), "--no-render"]
    return ["run", rel, "--out", str(out_dir), "--no-render"]


# ----------------------------------------------------------------------------
# all subprocess runs of this module, launched together


class _Run:
    def __init__(self, returncode, stdout, stderr, out_dir, timed_out=False, seconds=0.0, rss_mib=0.0):
        self.returncode = returncode
        self.stdout = stdout
        self.stderr = stderr
        self.out_dir = out_dir
        self.timed_out = timed_out
        self.seconds = seconds
        self.rss_mib = rss_mib
        self.before: list[str] = []


def _env() -> dict:
    return dict(os.environ, SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy")


def _run(args, out_dir: Path, timeout: float = 120.0, prefix=()) -> _Run:
    """Run the installed ``swarmform`` script (after ``prefix``, e.g. prlimit)."""
    try:
        p = subprocess.run(
            list(prefix) + SWARMFORM + list(args), cwd=ROOT, env=_env(), capture_output=True, text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired as exc:
        return _Run(None, exc.stdout or "", exc.stderr or "", out_dir, timed_out=True)
    return _Run(p.returncode, p.stdout, p.stderr, out_dir)


# Imports the command once, then forks one child per job, a few at a time.
# A child limits its address space and does what the console script does,
# ``sys.exit(main())``, including the interpreter's handling of an uncaught
# exception (traceback on stderr, exit status 1).
_FORK_DRIVER = r"""
import json, os, resource, signal, sys, time, traceback
import sim.cli, sim.output.media, sim.output.render, sim.runner  # everything the commands import
import scipy.optimize, scipy.spatial, shapely  # and import lazily

def child(job):
    code = 1
    try:
        for fd, name in ((1, job["stdout"]), (2, job["stderr"])):
            os.dup2(os.open(name, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644), fd)
        if job["address_space"]:
            resource.setrlimit(resource.RLIMIT_AS, (job["address_space"], job["address_space"]))
        sys.argv = ["swarmform", *job["argv"]]
        try:
            code = sim.cli.main()
        except SystemExit as exc:
            code = exc.code
        if code is None:
            code = 0
        elif not isinstance(code, int):
            print(code, file=sys.stderr)
            code = 1
    except BaseException:
        traceback.print_exc()
        code = 1
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)

jobs = json.loads(sys.argv[1])
todo = list(jobs.items())
running = {}
results = {}
while todo or running:
    while todo and len(running) < 4:
        key, job = todo.pop(0)
        sys.stdout.flush()
        sys.stderr.flush()
        t0 = time.monotonic()
        pid = os.fork()
        if pid == 0:
            child(job)
        running[key] = (pid, t0, t0 + job["timeout"])
    for key, (pid, t0, deadline) in list(running.items()):
        done, status, usage = os.wait4(pid, os.WNOHANG)
        timed_out = False
        if not done:
            if time.monotonic() <= deadline:
                continue
            os.kill(pid, signal.SIGKILL)
            _, status, usage = os.wait4(pid, 0)
            timed_out = True
        results[key] = {"returncode": None if timed_out else os.waitstatus_to_exitcode(status),
                        "timed_out": timed_out, "seconds": time.monotonic() - t0,
                        "rss_mib": usage.ru_maxrss / 1024}
        del running[key]
    time.sleep(0.005)
print(json.dumps(results))
"""


def _run_forked(jobs: dict, base: Path) -> dict:
    """Run ``{key: (argv, out_dir, timeout, address_space)}`` through the fork driver."""
    spec = {}
    for key, (argv, _out_dir, timeout, address_space) in jobs.items():
        logs = base / "logs" / key.replace(":", "-")
        logs.mkdir(parents=True)
        spec[key] = {
            "argv": argv,
            "stdout": str(logs / "stdout"),
            "stderr": str(logs / "stderr"),
            "timeout": timeout,
            "address_space": address_space,
        }
    p = subprocess.run(
        [sys.executable, "-c", _FORK_DRIVER, json.dumps(spec)],
        cwd=ROOT,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, p.stderr
    status = json.loads(p.stdout.splitlines()[-1])
    out = {}
    for key, (_argv, out_dir, _timeout, _) in jobs.items():
        st = status[key]
        out[key] = _Run(
            st["returncode"],
            Path(spec[key]["stdout"]).read_text(errors="replace"),
            Path(spec[key]["stderr"]).read_text(errors="replace"),
            out_dir,
            timed_out=st["timed_out"],
            seconds=st["seconds"],
            rss_mib=st["rss_mib"],
        )
    return out


HUGE_COUNT = """\
robots: {count: 400}
start: {formation: random}
target: {formation: line}
"""

# Corpus files that also run through the installed script, under prlimit.
SCRIPT_BAD = ("python-tag.yaml", "yaml-alias-bomb.yaml", "plan-huge-integer.json", "file-dev-zero.yaml")

# Wrong command lines, unreadable inputs and unwritable output paths:
# key -> (argv with {d} for the case's folder, a piece of the one-line
# message).  Each case's folder is empty or holds what ``_prepare`` puts
# there, and must not change.
OPTION_CASES = {
    "show-output-jpg": (["show", str(FIG1), "-o", "{d}/x.jpg"], "show writes PNG images only"),
    "set-anchor": (["run", str(FIG1), "--no-render", "--out", "{d}", "--set", "robots.margin=&a 0.1"],
                   "--set robots.margin: value '&a 0.1': anchors (&name) are not allowed"),
    "set-sexagesimal": (["run", str(FIG1), "--no-render", "--out", "{d}", "--set", "planner.time_limit=1:00"],
                        "--set planner.time_limit: must be a number in (0, 3600], got string '1:00'"),
    "set-tag": (["run", str(FIG1), "--no-render", "--out", "{d}", "--set", "robots.margin=!!python/name:os.system"],
                "is not allowed (only YAML's own"),
    "argv-nothing": ([], "required: COMMAND"),
    "argv-unknown-command": (["fly"], "invalid choice"),
    "argv-formations-extra": (["formations", "extra"], "unrecognized arguments"),
    "argv-show-no-scenario": (["show"], "required: scenario"),
    "argv-run-unknown-option": (["run", str(FIG1), "--colour", "x" * 5000], "unrecognized arguments"),
    "argv-plan-time-limit-text": (["plan", str(FIG1), "--time-limit", "soon"], "--time-limit"),
    "argv-plan-time-limit-huge": (["plan", str(FIG1), "--time-limit", "1e12"], "(0, 3600]"),
    "argv-tune-g-zero": (["tune", str(FIG1), "--g", "0", "--q", "5"], "--g"),
    "seed-negative": (["show", str(FIG1), "--seed", "-3", "-o", "{d}/x.png"], "--seed"),
    "seed-text": (["show", str(FIG1), "--seed", "abc", "-o", "{d}/x.png"], "--seed"),
    "seed-5000-digits": (["run", str(FIG1), "--seed", "7" * 5000, "--out", "{d}"], "--seed"),
    "show-size-zero": (["show", str(FIG1), "--size", "0", "-o", "{d}/x.png"], "--size"),
    "show-size-huge": (["show", str(FIG1), "--size", "100000", "-o", "{d}/x.png"], "--size"),
    "missing": (["run", "{d}/no-such-scenario.yaml", "--out", "{d}"], "no such file"),
    "scenario-folder": (["run", "{d}/folder.yaml", "--out", "{d}"], "is a folder"),
    "scenario-fifo": (["run", "{d}/fifo.yaml", "--out", "{d}"], "is a FIFO"),
    "plan-fifo": (["run", str(PLAN_BASE), "--plan", "{d}/fifo.json", "--out", "{d}"], "is a FIFO"),
    "scenario-long-path": (["run", "{d}/" + "p" * 300 + "/" + "q" * 5000 + ".yaml", "--out", "{d}"], ": file: "),
    "run-out-is-a-file": (["run", str(FIG1), "--out", "{d}/taken"], "is a file, not a folder"),
    "run-out-under-a-file": (["run", str(FIG1), "--out", "{d}/taken/sub"], "taken"),
    "run-report-is-a-folder": (["run", str(FIG1), "--out", "{d}"], "is a folder"),
    "plan-o-folder": (["plan", str(FIG1), "-o", "{d}"], "is a folder"),
    "plan-o-under-a-file": (["plan", str(FIG1), "-o", "{d}/taken/p.json"], "taken"),
    "plan-o-long-name": (["plan", str(FIG1), "-o", "{d}/" + "n" * 300 + ".json"], "longer than"),
    "show-o-folder": (["show", str(FIG1), "-o", "{d}"], "is a folder"),
    "show-o-trailing-slash": (["show", str(FIG1), "-o", "{d}/new/"], "names a folder"),
}


def _prepare(key: str, d: Path) -> None:
    """What a case's folder holds before the run (an obstacle to the output path)."""
    if key in ("scenario-fifo", "plan-fifo"):
        os.mkfifo(d / ("fifo.yaml" if key == "scenario-fifo" else "fifo.json"))
    elif key == "scenario-folder":
        (d / "folder.yaml").mkdir()
    elif key.endswith(("is-a-file", "under-a-file")):
        (d / "taken").write_text("a file in the way\n")
    elif key == "run-report-is-a-folder":
        (d / "fig1-line-to-phi.json").mkdir()


def _listing(d: Path) -> list[str]:
    return sorted(str(p.relative_to(d)) for p in d.rglob("*")) if d.exists() else []


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Every process this module checks, keyed by name, started together."""
    base = tmp_path_factory.mktemp("cli")

    def out_dir(key):
        d = base / key.replace(":", "-")
        d.mkdir()
        return d

    forked = {}
    for path in BAD_FILES:
        key = f"bad:{path.name}"
        d = out_dir(key)
        forked[key] = (_argv(path, d), d, SECONDS, ADDRESS_SPACE)
    d = out_dir("huge-count")
    (d / "huge.yaml").write_text(HUGE_COUNT)
    forked["huge-count"] = (["show", str(d / "huge.yaml"), "-o", str(d / "x.png")], d, 3.0, ADDRESS_SPACE)
    for key, (args, _) in OPTION_CASES.items():
        d = out_dir(key)
        _prepare(key, d)
        forked[key] = ([a.replace("{d}", str(d)) for a in args], d, SECONDS, ADDRESS_SPACE)
    before = {key: _listing(job[1]) for key, job in forked.items()}

    scripted = {}
    limit = ("prlimit", f"--as={ADDRESS_SPACE}", "--") if shutil.which("prlimit") else ()
    for name in SCRIPT_BAD:
        d = out_dir(f"script:{name}")
        scripted[f"script:{name}"] = (_argv(BAD / name, d), d, limit)
    for key, args in {
        "formations": ["formations"],
        "show": ["show", str(FIG1), "-o", "{d}/fig1.png"],
    }.items():
        d = out_dir(key)
        scripted[key] = ([a.replace("{d}", str(d)) for a in args], d, ())

    with ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 2)) as pool:
        fork_future = pool.submit(_run_forked, forked, base)
        futures = {k: pool.submit(_run, a, d, 120.0, pre) for k, (a, d, pre) in scripted.items()}
        results = {k: f.result() for k, f in futures.items()}
        results.update(fork_future.result())
    for key, listing in before.items():
        results[key].before = listing
    return results


# ----------------------------------------------------------------------------
# the bad-input corpus


def test_corpus_table_names_every_file():
    names = {p.name for p in BAD_FILES}
    assert names == set(CORPUS), (sorted(names - set(CORPUS)), sorted(set(CORPUS) - names))
    assert len(names) >= 60
    required = {
        "unknown-top-level-key.yaml", "unknown-robots-key.yaml", "radius-wrong-type.yaml",
        "radius-negative.yaml", "points-overlap.yaml", "point-inside-obstacle.yaml",
        "point-outside-workspace.yaml", "points-length-mismatch.yaml", "count-mismatch-points.yaml",
        "unknown-formation.yaml", "formation-too-big.yaml", "python-tag.yaml", "duplicate-key.yaml",
        "empty.yaml", "polygon-self-intersecting.yaml", "planner-g-zero.yaml", "yaml-syntax-error.yaml",
        "missing-target.yaml", "letter-count-mismatch.yaml",
        # the classes of hostile input
        "yaml-alias-bomb.yaml", "yaml-nesting-flow.yaml", "file-too-big.yaml", "file-dev-zero.yaml",
        "file-binary-garbage.yaml", "radius-tiny.yaml", "radius-huge.yaml", "max-speed-inf.yaml",
        "workspace-inf.yaml", "count-5000-digits.yaml", "radius-boolean.yaml", "radius-nan.yaml",
        "sim-dt-tiny.yaml", "sim-substeps-billion.yaml", "sim-settle-time-huge.yaml",
        "render-fps-billion-mp4.yaml", "render-speedup-tiny.yaml", "render-size-million.yaml",
        "render-size-20000.yaml", "planner-n-billion.yaml", "planner-extra-billion.yaml",
        "planner-q-huge.yaml", "name-250-characters.yaml", "name-100k-characters.yaml",
        "obstacles-random-10000.yaml", "polygon-10000-vertices.yaml", "polygon-bowtie.yaml",
        "plan-huge-integer.json", "plan-duration-tiny.json", "plan-waypoints-strings.json",
        "plan-radius-mismatch.json", "plan-too-fast.json", "plan-too-much-acceleration.json",
        "budget-slow-robots.yaml", "plan-physics-budget.json",
    }
    assert required <= names, sorted(required - names)
    assert (BAD / "file-dev-zero.yaml").is_symlink()  # a character device, kept as a link in git


def _check_one_line(r: _Run, *pieces: str) -> str:
    assert not r.timed_out, "still running"
    assert "Traceback" not in r.stderr, r.stderr[-2000:]
    assert r.returncode == 2, r.stderr[-2000:]
    lines = r.stderr.splitlines()
    assert len(lines) == 1, r.stderr[-2000:]
    line = lines[0]
    assert len(line) <= LINE_MAX, line
    for piece in pieces:
        assert piece in line, (piece, line)
    return line


def _check_bad_run(path: Path, r: _Run):
    field, says = CORPUS[path.name]
    # "swarmform: error: FILE: FIELD: reason"
    line = _check_one_line(r, f"{path.relative_to(ROOT)}: {field}: ", says)
    assert line.startswith("swarmform: error: ")
    if path.name not in AFTER_PLANNING:
        assert r.stdout == ""  # refused before any work
    assert _listing(r.out_dir) == []  # nothing written, nothing half-written left behind


@pytest.mark.parametrize("path", BAD_FILES, ids=lambda p: p.name)
def test_bad_file_exits_2_with_one_line(path, runs):
    r = runs[f"bad:{path.name}"]
    _check_bad_run(path, r)
    assert r.seconds < SECONDS


def test_corpus_runs_are_quick_and_small(runs):
    """Under the 2 GiB address-space limit every run is fast and stays far below it."""
    rs = [runs[f"bad:{p.name}"] for p in BAD_FILES]
    assert all(r.returncode == 2 for r in rs)
    assert max(r.seconds for r in rs) < SECONDS
    assert max(r.rss_mib for r in rs) < 1024


@pytest.mark.parametrize("name", SCRIPT_BAD)
def test_bad_file_through_the_installed_script(name, runs):
    _check_bad_run(BAD / name, runs[f"script:{name}"])


@pytest.mark.parametrize("path", [p for p in BAD_FILES if p.suffix == ".yaml" and p.name not in AFTER_PLANNING],
                         ids=lambda p: p.name)
def test_bad_file_raises_scenario_error(path):
    field, says = CORPUS[path.name]
    with pytest.raises(ScenarioError) as info:
        scenario = read_scenario(path)
        build_problem(scenario, np.random.default_rng(scenario.seed))
    exc = info.value
    assert exc.field.startswith(field), (exc.field, field)
    assert exc.path == str(path)
    assert "\n" not in str(exc)
    assert str(exc).startswith(f"{path}: {exc.field}: ")
    assert says in str(exc)


@pytest.mark.parametrize("key", list(OPTION_CASES))
def test_wrong_options_and_paths_exit_2_with_one_line(key, runs):
    """Argument errors of every subcommand, unreadable inputs, unwritable outputs: before any work."""
    r = runs[key]
    _check_one_line(r, OPTION_CASES[key][1])
    assert r.stdout == ""
    assert r.seconds < SECONDS
    assert _listing(r.out_dir) == r.before  # the folder is as it was


def test_python_tags_are_never_executed(tmp_path):
    marker = tmp_path / "executed"
    path = tmp_path / "tag.yaml"
    path.write_text(
        textwrap.dedent(
            f"""\
            start: {{formation: A}}
            target: !!python/object/apply:os.system ["touch {marker}"]
            name: !!python/object/apply:builtins.exec ["open('{marker}', 'w').close()"]
            """
        )
    )
    with pytest.raises(ScenarioError) as info:
        read_scenario(path)
    assert info.value.field.startswith("line 2")
    assert not marker.exists()


def test_impossible_count_is_refused_promptly(runs):
    r = runs["huge-count"]
    assert not r.timed_out, "still running after 3 s"
    assert r.returncode == 2
    assert "robots.count" in r.stderr or "start" in r.stderr


# ----------------------------------------------------------------------------
# formations and show


def test_formations_lists_all_with_counts(runs):
    r = runs["formations"]
    assert r.returncode == 0, r.stderr
    rows = {line.split()[0]: line.split(None, 1)[1] for line in r.stdout.splitlines()[1:] if line.strip()}
    assert set(rows) == set(DEFAULT_COUNTS) | {"scatter", "text", "strokes"}
    for name, count in [*DEFAULT_COUNTS.items(), ("scatter", None), ("text", None), ("strokes", None)]:
        if count is None:
            assert "robots.count" in rows[name]
        else:
            assert rows[name].strip() == str(count)


def test_show_writes_a_png(runs):
    r = runs["show"]
    assert r.returncode == 0, r.stderr
    png = r.out_dir / "fig1.png"
    assert str(png) in r.stdout
    img = iio.imread(png)
    assert img.ndim == 3 and img.shape[2] in (3, 4) and img.dtype == np.uint8
    h, w = img.shape[:2]
    assert h % 2 == 0 and w % 2 == 0
    assert min(h, w) >= 200
    colours = np.unique(img[..., :3].reshape(-1, 3), axis=0)
    assert len(colours) >= 6  # background, walls, obstacles, start, target, text
    assert [p.name for p in r.out_dir.iterdir()] == ["fig1.png"]  # no temporary left


def test_missing_file_names_the_path(runs):
    r = runs["missing"]
    assert r.returncode == 2
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr
    assert str(r.out_dir / "no-such-scenario.yaml") in lines[0]
    assert not (r.out_dir / "x.png").exists()


@pytest.mark.parametrize("key", ["seed-negative", "seed-text"])
def test_bad_seed_exits_2(runs, key):
    r = runs[key]
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert "--seed" in r.stderr
    assert not (r.out_dir / "x.png").exists()


def _show(tmp_path, scenario, seed, name):
    out = tmp_path / name
    argv = ["show", str(scenario), "-o", str(out)]
    if seed is not None:
        argv += ["--seed", str(seed)]
    assert main(argv) == 0
    return out


def test_seed_changes_the_picture_only_where_random(tmp_path):
    """Another seed moves a random start; a fixed scenario changes only in its title."""
    a = _show(tmp_path, FIG2, 2, "a.png")
    again = _show(tmp_path, FIG2, 2, "again.png")
    default = _show(tmp_path, FIG2, None, "default.png")  # the file's seed is 2
    b = _show(tmp_path, FIG2, 3, "b.png")
    assert a.read_bytes() == again.read_bytes() == default.read_bytes()
    assert a.read_bytes() != b.read_bytes()

    f2 = iio.imread(_show(tmp_path, FIXED, 2, "f2.png"))
    f3 = iio.imread(_show(tmp_path, FIXED, 3, "f3.png"))
    assert f2.shape == f3.shape
    fixed_rows = np.flatnonzero((f2 != f3).any(axis=(1, 2)))
    # the title ("... seed N") is the only difference of the fixed scenario, at the top
    assert len(fixed_rows) > 0
    band = int(fixed_rows.max()) + 1
    assert band < f2.shape[0] // 6
    ia, ib = iio.imread(a), iio.imread(b)
    random_rows = np.flatnonzero((ia != ib).any(axis=(1, 2)))
    assert random_rows.max() >= band, "only the title changed with the seed"


def test_show_default_output_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["show", str(FIG1)]) == 0
    out = tmp_path / "media" / "fig1-line-to-phi-scenario.png"
    assert iio.imread(out).shape[2] in (3, 4)
    assert [p.name for p in (tmp_path / "media").iterdir()] == [out.name]


@pytest.mark.parametrize("name", ["yaml-alias-bomb.yaml", "yaml-nesting-flow.yaml", "file-too-big.yaml",
                                  "count-5000-digits.yaml", "file-dev-zero.yaml"])
def test_expanding_inputs_are_refused_in_milliseconds(name):
    """Refused before anything is expanded or read in full: well under 50 ms in-process."""
    t0 = time.perf_counter()
    with pytest.raises(ScenarioError):
        read_scenario(BAD / name)
    assert time.perf_counter() - t0 < 0.05
