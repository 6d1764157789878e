"""Where a command's files go: checked before any work, built aside, replaced as a set.

* :func:`check_out_dir` and :func:`check_out_file` refuse, with an
  :class:`OutputPathError` naming the option, an output path that cannot be
  written: a folder given where a file goes or the reverse, a missing
  parent that cannot be made, a folder without write permission or on a
  read-only file system, a name too long for the file system.  They write
  nothing; the commands call them before reading or planning anything.
* :class:`OutputSet` holds the files of one run (``NAME.json``, the videos,
  and whatever else :data:`RUN_OUTPUTS` lists).  They are written into a
  staging folder beside them, ``DIR/.NAME.tmp-PID/``, and moved into place
  only by :meth:`OutputSet.commit`, with SIGINT and SIGTERM held back for
  the few renames; a member the run did not make is removed then, so the
  folder never mixes files of two runs.  Until the commit the old set is
  untouched: an error or an interrupt (in the planner, the physics, the MP4
  encoder) only removes the staging folder.
* Temporary names carry the PID of the process that made them
  (``.NAME.tmp-PID`` and ``.FILE.tmp-PID-XXXX.EXT``); :func:`remove_stale`
  deletes those of the same name left by a process that no longer runs
  (after a SIGKILL, a power cut), and is called whenever such a name is
  about to be made again.
"""

from __future__ import annotations

import errno
import os
import re
import shutil
import signal
import stat
import threading
from contextlib import contextmanager
from pathlib import Path

from planner.inputfile import echo_path

from ..errors import InputError
from ..stops import STOP_SIGNALS

__all__ = [
    "RUN_OUTPUTS",
    "OutputPathError",
    "OutputSet",
    "check_out_dir",
    "check_out_file",
    "remove_stale",
    "temp_name",
]

RUN_OUTPUTS = (
    "{name}.json",  # the run report
    "{name}.gif",
    "{name}.mp4",
    "{name}.html",  # the run page
    "{name}-series.npz",  # the physics run's time series
)
"""The files of one run, replaced as a set; adding an output is adding a line here."""

_NAME_MAX = 255 - 28  # room for ".tmp-PID-XXXXXXXX" and a leading dot within NAME_MAX
_TEMP_RE = re.compile(r"\.(?P<name>.+)\.tmp-(?P<pid>[0-9]+)(?:-[A-Za-z0-9_]+(?:\.[A-Za-z0-9]+)?)?")


class OutputPathError(InputError):
    """An output path that cannot be written: one line naming the option, the path and why."""

    def __init__(self, option: str, path, reason: str):
        self.option, self.path, self.reason = option, str(path), reason
        super().__init__(f"{option}: {echo_path(path)}: {reason}")


# ----------------------------------------------------------------------------
# checks before any work


def check_out_dir(path: str | Path, option: str = "--out") -> Path:
    """``path`` as a folder that exists and is writable, or can be made; raise otherwise."""
    path = _as_path(path, option)
    st = _stat(path, option)
    if st is None:
        _check_makeable(path, option)
    elif not stat.S_ISDIR(st.st_mode):
        raise OutputPathError(option, path, "is a file, not a folder")
    else:
        _check_writable(path, path, option)
    return path


def check_out_file(path: str | Path, option: str) -> Path:
    """``path`` as a file that can be written (made or replaced); raise otherwise."""
    text = os.fspath(path)
    path = _as_path(path, option)
    if path.name in ("", ".", "..") or str(text).endswith(("/", os.sep)):
        raise OutputPathError(option, path, "names a folder; give a file name")
    if len(os.fsencode(path.name)) > _NAME_MAX:
        raise OutputPathError(option, path, f"the file name is longer than {_NAME_MAX} bytes")
    st = _stat(path, option)
    if st is not None:
        if stat.S_ISDIR(st.st_mode):
            raise OutputPathError(option, path, "is a folder; give a file name")
        if not stat.S_ISREG(st.st_mode):
            raise OutputPathError(option, path, "exists and is not a regular file")
    check_out_dir(path.parent, option)
    return path


def _as_path(path, option: str) -> Path:
    text = os.fspath(path)
    if not text:
        raise OutputPathError(option, "''", "is empty")
    if "\0" in str(text):
        raise OutputPathError(option, path, "holds a NUL character")
    return Path(text)


def _stat(path: Path, option: str):
    try:
        return os.stat(path)
    except FileNotFoundError:
        return None
    except NotADirectoryError:
        raise OutputPathError(option, path, "a part of the path is a file, not a folder") from None
    except OSError as exc:
        raise OutputPathError(option, path, _reason(exc)) from None


def _check_makeable(path: Path, option: str) -> None:
    """A missing folder: its nearest existing ancestor must be a writable folder."""
    parent = path
    while True:
        parent = parent.parent
        st = _stat(parent, option)
        if st is not None:
            break
        if parent == parent.parent:
            raise OutputPathError(option, path, "cannot be made: no part of the path exists")
    if not stat.S_ISDIR(st.st_mode):
        raise OutputPathError(option, path, f"cannot be made: {echo_path(parent, 60)} is a file")
    _check_writable(parent, path, option)


def _check_writable(folder: Path, path: Path, option: str) -> None:
    where = "" if folder == path else f" ({echo_path(folder, 60)})"
    try:
        read_only = bool(os.statvfs(folder).f_flag & os.ST_RDONLY)
    except OSError:
        read_only = False
    if read_only:
        raise OutputPathError(option, path, f"the folder{where} is on a read-only file system")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputPathError(option, path, f"the folder{where} is not writable")


def _reason(exc: OSError) -> str:
    return os.strerror(exc.errno) if exc.errno in errno.errorcode else type(exc).__name__


# ----------------------------------------------------------------------------
# temporary names and stale ones


def temp_name(final_name: str, token: str = "") -> str:
    """The hidden temporary name of ``final_name`` for this process.

    A folder's is ``.NAME.tmp-PID``; a file's (with a ``token``) is
    ``.NAME.tmp-PID-TOKEN.EXT``, ending in the final name's extension, which
    writers such as ffmpeg go by.
    """
    if not token:
        return f".{final_name}.tmp-{os.getpid()}"
    return f".{final_name}.tmp-{os.getpid()}-{token}{Path(final_name).suffix}"


def remove_stale(folder: Path, names) -> list[Path]:
    """Remove temporaries of ``names`` in ``folder`` whose process is gone; return them."""
    names = set(names)
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        m = _TEMP_RE.fullmatch(entry.name)
        if not m or m.group("name") not in names or _alive(int(m.group("pid"))):
            continue
        path = Path(entry.path)
        try:
            if entry.is_dir(follow_symlinks=False):
                shutil.rmtree(path)
            else:
                path.unlink()
        except FileNotFoundError:
            continue
        removed.append(path)
    return removed


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    if pid <= 0 or pid > 2**22:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # someone else's process
    return True


@contextmanager
def signals_held():
    """Hold SIGINT, SIGTERM, SIGHUP and SIGQUIT back until the block ends, then act on them.

    Python-level handlers that only note the signal (they run in the main
    thread whatever thread the system delivers the signal to, unlike a
    thread's signal mask); when the block ends the old handlers come back
    and each noted signal is raised again (SIGINT: ``KeyboardInterrupt``).
    Outside the main thread the block runs as it is.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    noted: list[int] = []
    old = {}
    for sig in (signal.SIGINT, *STOP_SIGNALS):
        handler = signal.getsignal(sig)
        if handler is None:  # installed outside Python: leave it alone
            continue
        old[sig] = signal.signal(sig, lambda signum, _frame: noted.append(signum))
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
        for sig in dict.fromkeys(noted):
            signal.raise_signal(sig)


# ----------------------------------------------------------------------------
# the files of a run


class OutputSet:
    """The files ``DIR/NAME.*`` of one run, replaced together (see the module docstring).

    Use as a context manager::

        outs = OutputSet(out_dir, name)
        outs.check()                        # before any work
        with outs:                          # makes DIR/.NAME.tmp-PID/
            write(outs.path("NAME.json"))   # into the staging folder
            outs.commit()                   # everything moves into DIR
    """

    def __init__(self, out_dir: str | Path, name: str, members=RUN_OUTPUTS, option: str = "--out"):
        self.out_dir = Path(out_dir)
        self.name = name
        self.members = tuple(m.format(name=name) for m in members)
        self.option = option
        self.staging: Path | None = None
        self.committed = False
        self._made: list[Path] = []

    def final(self, member: str) -> Path:
        """Where ``member`` ends up after the commit."""
        return self.out_dir / member

    def path(self, member: str) -> Path:
        """Where to write ``member`` now (inside the staging folder)."""
        if member not in self.members:
            raise ValueError(f"{member!r} is not one of this run's outputs {self.members}")
        if self.staging is None:
            raise RuntimeError("OutputSet.path() outside its with-block")
        return self.staging / member

    @property
    def stem(self) -> Path:
        """``staging/NAME``: the stem the video writer adds ``.gif`` and ``.mp4`` to."""
        if self.staging is None:
            raise RuntimeError("OutputSet.stem outside its with-block")
        return self.staging / self.name

    def check(self) -> None:
        """Raise :class:`OutputPathError` unless every member can be written; write nothing."""
        check_out_dir(self.out_dir, self.option)
        for member in self.members:
            st = _stat(self.out_dir / member, self.option)
            if st is not None and stat.S_ISDIR(st.st_mode):
                raise OutputPathError(self.option, self.out_dir / member,
                                      "is a folder, so the run's file of that name cannot replace it")

    def __enter__(self) -> "OutputSet":
        self.check()
        missing = []
        p = self.out_dir
        while not p.exists() and p != p.parent:
            missing.append(p)
            p = p.parent
        try:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            self._made = missing[::-1]
            remove_stale(self.out_dir, (self.name, *self.members))
            staging = self.out_dir / temp_name(self.name)
            if staging.exists():  # left by an earlier run of this very process
                shutil.rmtree(staging)
            staging.mkdir()
        except OSError as exc:
            self._remove_made()
            raise OutputPathError(self.option, self.out_dir, f"cannot be written ({_reason(exc)})") from None
        self.staging = staging
        return self

    def commit(self) -> list[Path]:
        """Move every staged member into place, remove the members not made; return the files."""
        if self.staging is None or self.committed:
            raise RuntimeError("OutputSet.commit() outside its with-block or twice")
        done = []
        with signals_held():
            for member in self.members:
                staged, final = self.staging / member, self.final(member)
                if staged.exists():
                    os.replace(staged, final)
                    done.append(final)
                else:
                    try:
                        final.unlink()
                    except FileNotFoundError:
                        pass
            self.committed = True
            shutil.rmtree(self.staging, ignore_errors=True)
        return done

    def __exit__(self, exc_type, exc, tb) -> None:
        if self.staging is not None and not self.committed:
            shutil.rmtree(self.staging, ignore_errors=True)
            self._remove_made()
        self.staging = None

    def _remove_made(self) -> None:
        """Remove the folders this set made, when nothing else went into them."""
        for p in reversed(self._made):
            try:
                p.rmdir()
            except OSError:
                break
        self._made = []
