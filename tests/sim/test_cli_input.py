"""The command line and bad input: exit codes, one-line messages, pictures.

``tests/data/bad/`` holds malformed scenario files.  Each starts with
comment lines that say what the error must name::

    # field: robots.radius        (required: the field the message names)
    # says: must be > 0           (optional: a piece of the reason)
    # xfail: ...                  (optional: a known defect, with where it is)

For each file ``swarmform show FILE -o OUT.png`` must exit 2 with exactly
one line on stderr naming the file and the field, no traceback, and no
picture written; in-process, reading and building must raise
:class:`ScenarioError` with that field.

Starting the interpreter and importing numpy, scipy and pygame costs more
than a second, so the corpus runs in one helper process that imports the
command once and forks a child per file: each child runs ``sim.cli.main``
exactly as the ``swarmform`` console script does (``sys.exit(main())``,
uncaught exceptions print a traceback and exit 1) with its own stdout,
stderr and exit status.  One corpus file, ``swarmform formations`` and
``swarmform show`` of a paper figure also run the installed script itself.
All of these processes are started together by one module fixture.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from planner.formations import DEFAULT_COUNTS
from sim.cli import main
from sim.scenario import ScenarioError, build_problem, read_scenario

ROOT = Path(__file__).resolve().parents[2]
BAD = ROOT / "tests" / "data" / "bad"
BAD_FILES = sorted(BAD.glob("*.yaml"))
FIG1 = ROOT / "scenarios" / "paper" / "fig1-line-to-phi.yaml"
FIG2 = ROOT / "scenarios" / "paper" / "fig2-random-to-C.yaml"  # random start
FIXED = ROOT / "scenarios" / "letters" / "line-to-A.yaml"  # rotations and centres given

_SCRIPT = Path(sys.executable).with_name("swarmform")
SWARMFORM = [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "sim.cli"]


def _header(path: Path) -> dict[str, str]:
    out = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("# ") or ":" not in line:
            break
        key, value = line[2:].split(":", 1)
        out[key.strip()] = value.strip()
    return out


def _params():
    for path in BAD_FILES:
        head = _header(path)
        marks = [pytest.mark.xfail(strict=True, reason=head["xfail"])] if "xfail" in head else []
        yield pytest.param(path, marks=marks, id=path.stem)


BAD_CASES = list(_params())


# ----------------------------------------------------------------------------
# all subprocess runs of this module, launched together


class _Run:
    def __init__(self, returncode, stdout, stderr, out_dir, timed_out=False):
        self.returncode = returncode
        self.stdout = stdout
        self.stderr = stderr
        self.out_dir = out_dir
        self.timed_out = timed_out


def _env() -> dict:
    return dict(os.environ, SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy")


def _run(args, out_dir: Path, timeout: float = 120.0) -> _Run:
    """Run the installed ``swarmform`` script."""
    try:
        p = subprocess.run(
            SWARMFORM + list(args), cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=timeout
        )
    except subprocess.TimeoutExpired as exc:
        return _Run(None, exc.stdout or "", exc.stderr or "", out_dir, timed_out=True)
    return _Run(p.returncode, p.stdout, p.stderr, out_dir)


# Imports the command once, then forks one child per job.  A child does what
# the console script does, ``sys.exit(main())``, including the interpreter's
# handling of an uncaught exception (traceback on stderr, exit status 1).
_FORK_DRIVER = r"""
import json, os, signal, sys, time, traceback
import sim.cli, sim.media, sim.render  # everything `swarmform show` imports

def child(job):
    code = 1
    try:
        for fd, name in ((1, job["stdout"]), (2, job["stderr"])):
            os.dup2(os.open(name, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644), fd)
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
pids = {}
for key, job in jobs.items():
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:
        child(job)
    pids[key] = (pid, time.monotonic() + job["timeout"])
results = {}
while pids:
    for key, (pid, deadline) in list(pids.items()):
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            results[key] = {"returncode": os.waitstatus_to_exitcode(status), "timed_out": False}
        elif time.monotonic() > deadline:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            results[key] = {"returncode": None, "timed_out": True}
        else:
            continue
        del pids[key]
    time.sleep(0.01)
print(json.dumps(results))
"""


def _run_forked(jobs: dict, base: Path) -> dict:
    """Run ``{key: (argv, out_dir, timeout)}`` through the fork driver."""
    spec = {}
    for key, (argv, out_dir, timeout) in jobs.items():
        logs = base / "logs" / key.replace(":", "-")
        logs.mkdir(parents=True)
        spec[key] = {
            "argv": argv,
            "stdout": str(logs / "stdout"),
            "stderr": str(logs / "stderr"),
            "timeout": timeout,
        }
    p = subprocess.run(
        [sys.executable, "-c", _FORK_DRIVER, json.dumps(spec)],
        cwd=ROOT,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert p.returncode == 0, p.stderr
    status = json.loads(p.stdout.splitlines()[-1])
    out = {}
    for key, (argv, out_dir, timeout) in jobs.items():
        st = status[key]
        out[key] = _Run(
            st["returncode"],
            Path(spec[key]["stdout"]).read_text(),
            Path(spec[key]["stderr"]).read_text(),
            out_dir,
            timed_out=st["timed_out"],
        )
    return out


HUGE_COUNT = """\
robots: {count: 400}
start: {formation: random}
target: {formation: line}
"""

# A corpus file that also runs through the installed script.
SCRIPT_BAD = ("python-tag",)


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
        key = f"bad:{path.stem}"
        d = out_dir(key)
        forked[key] = (["show", str(path.relative_to(ROOT)), "-o", str(d / "out.png")], d, 60.0)
    d = out_dir("huge-count")
    (d / "huge.yaml").write_text(HUGE_COUNT)
    forked["huge-count"] = (["show", str(d / "huge.yaml"), "-o", str(d / "x.png")], d, 3.0)
    for key, args in {
        "missing": ["show", "{d}/no-such-scenario.yaml", "-o", "{d}/x.png"],
        "seed-negative": ["show", str(FIG1), "--seed", "-3", "-o", "{d}/x.png"],
        "seed-text": ["show", str(FIG1), "--seed", "abc", "-o", "{d}/x.png"],
    }.items():
        d = out_dir(key)
        forked[key] = ([a.replace("{d}", str(d)) for a in args], d, 60.0)

    scripted = {}
    for stem in SCRIPT_BAD:
        d = out_dir(f"script:{stem}")
        scripted[f"script:{stem}"] = (["show", f"tests/data/bad/{stem}.yaml", "-o", str(d / "out.png")], d)
    for key, args in {
        "formations": ["formations"],
        "show": ["show", str(FIG1), "-o", "{d}/fig1.png"],
    }.items():
        d = out_dir(key)
        scripted[key] = ([a.replace("{d}", str(d)) for a in args], d)

    with ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 2)) as pool:
        fork_future = pool.submit(_run_forked, forked, base)
        futures = {k: pool.submit(_run, a, d) for k, (a, d) in scripted.items()}
        results = {k: f.result() for k, f in futures.items()}
        results.update(fork_future.result())
    return results


# ----------------------------------------------------------------------------
# the bad-input corpus


def test_corpus_covers_the_required_cases():
    stems = {p.stem for p in BAD_FILES}
    required = {
        "unknown-top-level-key",
        "unknown-robots-key",
        "radius-wrong-type",
        "radius-negative",
        "points-overlap",
        "point-inside-obstacle",
        "point-outside-workspace",
        "points-length-mismatch",
        "count-mismatch-points",
        "unknown-formation",
        "formation-too-big",
        "python-tag",
        "duplicate-key",
        "empty",
        "polygon-self-intersecting",
        "planner-g-zero",
        "yaml-syntax-error",
        "missing-target",
        "letter-count-mismatch",
    }
    assert required <= stems, sorted(required - stems)
    for path in BAD_FILES:
        assert path.read_text(encoding="utf-8").startswith("# field: "), path.name
        assert _header(path)["field"], path.name


def _check_bad_run(path: Path, r: _Run):
    head = _header(path)
    assert not r.timed_out
    assert "Traceback" not in r.stderr
    assert r.returncode == 2, r.stderr
    lines = r.stderr.splitlines()
    assert len(lines) == 1, r.stderr
    line = lines[0]
    # "swarmform: error: FILE: FIELD: reason"
    assert f"{path.relative_to(ROOT)}: {head['field']}" in line, line
    if "says" in head:
        assert head["says"] in line
    # nothing ran, nothing was drawn, nothing half-written was left behind
    assert r.stdout == ""
    assert list(r.out_dir.iterdir()) == []


@pytest.mark.parametrize("path", BAD_CASES)
def test_bad_file_exits_2_with_one_line(path, runs):
    _check_bad_run(path, runs[f"bad:{path.stem}"])


@pytest.mark.parametrize("stem", SCRIPT_BAD)
def test_bad_file_through_the_installed_script(stem, runs):
    _check_bad_run(BAD / f"{stem}.yaml", runs[f"script:{stem}"])


@pytest.mark.parametrize("path", BAD_CASES)
def test_bad_file_raises_scenario_error(path):
    head = _header(path)
    with pytest.raises(ScenarioError) as info:
        scenario = read_scenario(path)
        build_problem(scenario, np.random.default_rng(scenario.seed))
    exc = info.value
    assert exc.field.startswith(head["field"]), (exc.field, head["field"])
    assert exc.path == str(path)
    assert "\n" not in str(exc)
    assert str(exc).startswith(f"{path}: {exc.field}: ")
    if "says" in head:
        assert head["says"] in str(exc)


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
