"""The results file: JSON Lines, one row per finished run, appended by one sweep at a time.

What counts as a results file (the only files ``tune -o`` appends to): a
regular file, not a symbolic link, that is empty or whose every complete
line is a result row (a JSON object with the key fields of
:data:`~sim.tune.spec.KEY_FIELDS` and ``found``, of the right types).  After
the last newline there may be the start of a row cut short by a hard kill
(it begins ``{"scenario": ``); opening the file for a sweep cuts it off.
Anything else -- a notes file, a directory, a FIFO, a device, a symbolic
link -- is refused with a :class:`~sim.tune.spec.TuneError` (exit 2), and
the file is not written, truncated or even opened for writing.

Only the process that drives the sweep writes the file, each row as one
``write`` followed by an ``fsync``, so an interrupted sweep keeps every
finished row.  The summary files beside it (``NAME.md``, ``NAME.html``,
``NAME-*.png``) are replaced atomically.
"""

from __future__ import annotations

import errno
import json
import os
import stat
from pathlib import Path

from .spec import KEY_FIELDS, RunSpec, TuneError

__all__ = ["ResultsFile", "check_output", "read_results", "row_key", "summary_path"]

ROW_PREFIX = b'{"scenario": '
"""How every row written by a sweep begins (``json.dumps`` of a row: its first key is the scenario)."""

_CHUNK = 1 << 20
_SUMMARY_SUFFIXES = (".md", ".html")


def read_results(path: str | Path) -> list[dict]:
    """The rows of a results file, in file order.

    A torn last line (a sweep killed while writing) and lines that are not
    result rows are left out.  Raises :class:`TuneError` when the file
    cannot be read.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise TuneError(f"{path}: cannot read the results file: {exc.strerror or exc}") from None
    rows = []
    for line in data[: data.rfind(b"\n") + 1].splitlines():
        row = _row(line)
        if row is not None:
            rows.append(row)
    return rows


def row_key(row: dict) -> tuple:
    """The key of a row, as :attr:`RunSpec.key` (rows without ``settings`` have none)."""
    settings = row.get("settings") or {}
    return (row["scenario"], row["mode"], row["g"], row["q"], row["seed"], float(row["time_limit"]),
            row["simulate"], tuple(sorted(settings.items())))


def summary_path(results: Path, suffix: str) -> Path:
    """``NAME.md`` / ``NAME.html`` beside ``NAME.jsonl``."""
    return results.with_suffix(suffix)


def check_output(path: str | Path) -> Path:
    """Check ``-o`` before any run: an existing file must be one of ours; refuse links and the rest.

    Reads, never writes.  Also checks the folder and the summary files
    beside the results (``NAME.md``, ``NAME.html``: not directories).
    """
    path = Path(path)
    parent = path.parent
    for folder in (parent, *parent.parents):
        if os.path.lexists(folder):
            if not folder.is_dir():
                raise TuneError(f"--output: {folder}: is not a folder, so {path.name} cannot be written in it")
            if not os.access(folder, os.W_OK | os.X_OK) and folder == parent:
                raise TuneError(f"--output: {folder}: the folder is not writable")
            break
    _check_kind(path)
    if os.path.lexists(path):
        try:
            fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
        except OSError as exc:
            raise _open_error(path, exc) from None
        try:
            _check_kind(path, os.fstat(fd))
            _scan(path, _read_all(fd))
        finally:
            os.close(fd)
    for suffix in _SUMMARY_SUFFIXES:
        side = summary_path(path, suffix)
        if side.is_dir() and not side.is_symlink():
            raise TuneError(f"--output: {side}: is a directory; the sweep writes its summary there")
    return path


class ResultsFile:
    """The results file, open for appending by this process alone.

    Opening refuses what is not a results file (see the module), takes an
    exclusive lock (where the platform has ``fcntl``), so two sweeps never
    write one file, and cuts off a torn last line.  ``rows`` and ``keys``
    hold what the file had and what was appended since.
    """

    def __init__(self, path: str | Path, log):
        self.path = path = Path(path)
        check_output(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        flags = os.O_RDWR | os.O_APPEND | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
        try:
            try:
                self._fd = os.open(path, flags)
            except FileNotFoundError:
                self._fd = os.open(path, flags | os.O_CREAT | os.O_EXCL, 0o666)
        except OSError as exc:
            raise _open_error(path, exc) from None
        try:
            _check_kind(path, os.fstat(self._fd))
            self._lock()
            data = _read_all(self._fd)
            self.rows, end = _scan(path, data)
            if end < len(data):
                os.ftruncate(self._fd, end)
                os.fsync(self._fd)
                print(f"swarmform tune: {path}: cut off a torn last line ({len(data) - end} bytes)", file=log)
        except BaseException:
            os.close(self._fd)
            raise
        self.keys = {row_key(r) for r in self.rows}

    def _lock(self) -> None:
        # A POSIX record lock belongs to this process alone: forked workers do
        # not inherit it, so a worker outliving a killed sweep never blocks
        # the rerun; the system drops it when the process ends, however.
        try:
            import fcntl
        except ImportError:  # no advisory locks on this platform
            return
        try:
            fcntl.lockf(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise TuneError(f"{self.path}: is being written by another sweep") from None

    def has(self, spec: RunSpec) -> bool:
        return spec.key in self.keys

    def append(self, row: dict) -> None:
        """Add one row as one line: a single write (completed if short), then fsync."""
        data = (json.dumps(row, allow_nan=False, ensure_ascii=False) + "\n").encode("utf-8")
        if not data.startswith(ROW_PREFIX):
            raise ValueError(f"a row must begin with its scenario, got {data[:40]!r}")
        done = os.write(self._fd, data)
        while done < len(data):
            done += os.write(self._fd, data[done:])
        os.fsync(self._fd)
        self.rows.append(row)
        self.keys.add(row_key(row))

    def close(self) -> None:
        os.close(self._fd)


def _check_kind(path: Path, st: os.stat_result | None = None) -> None:
    """Refuse a symbolic link or anything but a regular file (``st``: of the open file)."""
    if st is None:
        try:
            st = os.lstat(path)
        except FileNotFoundError:
            return
        except OSError as exc:
            raise TuneError(f"--output: {path}: cannot be checked: {exc.strerror or exc}") from None
    mode = st.st_mode
    if stat.S_ISLNK(mode):
        raise TuneError(f"--output: {path}: is a symbolic link; a sweep never writes through one (give the real path)")
    if not stat.S_ISREG(mode):
        kind = ("a directory" if stat.S_ISDIR(mode) else "a FIFO" if stat.S_ISFIFO(mode) else
                "a socket" if stat.S_ISSOCK(mode) else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
                else "not a regular file")
        raise TuneError(f"--output: {path}: is {kind}, not a results file")


def _open_error(path: Path, exc: OSError) -> TuneError:
    if exc.errno == errno.ELOOP:
        return TuneError(f"--output: {path}: is a symbolic link; a sweep never writes through one (give the real path)")
    if exc.errno == errno.EISDIR:
        return TuneError(f"--output: {path}: is a directory, not a results file")
    return TuneError(f"--output: {path}: cannot open the results file: {exc.strerror or exc}")


def _read_all(fd: int) -> bytes:
    os.lseek(fd, 0, os.SEEK_SET)
    chunks = []
    while chunk := os.read(fd, _CHUNK):
        chunks.append(chunk)
    return b"".join(chunks)


def _scan(path: Path, data: bytes) -> tuple[list[dict], int]:
    """The rows of a results file and where its complete lines end; refuse a file that is not one."""
    end = data.rfind(b"\n") + 1
    tail = data[end:]
    rows = []
    for n, line in enumerate(data[:end].split(b"\n")[:-1], 1):
        row = _row(line)
        if row is None:
            raise TuneError(f"--output: {path}: is not a results file (line {n} is not a result row); "
                            "give a new file or one a sweep wrote")
        rows.append(row)
    if tail and not tail.startswith(ROW_PREFIX[: len(tail)]):
        raise TuneError(f"--output: {path}: is not a results file (its last line is not a result row); "
                        "give a new file or one a sweep wrote")
    return rows, end


def _row(line: bytes) -> dict | None:
    try:
        row = json.loads(line)
    except (ValueError, UnicodeDecodeError, RecursionError):
        return None
    return row if _is_row(row) else None


def _is_row(row) -> bool:
    if not isinstance(row, dict) or not all(k in row for k in (*KEY_FIELDS[:-1], "found")):
        return False
    ints = all(row[k] is None or (isinstance(row[k], int) and not isinstance(row[k], bool))
               for k in ("g", "q"))
    settings = row.get("settings", {})
    settings_ok = isinstance(settings, dict) and all(
        v is None or isinstance(v, (str, int, float, bool)) for v in settings.values())
    return (isinstance(row["scenario"], str) and row["mode"] in ("fixed", "auto") and ints
            and isinstance(row["seed"], int) and isinstance(row["time_limit"], (int, float))
            and not isinstance(row["time_limit"], bool)
            and isinstance(row["simulate"], bool) and isinstance(row["found"], bool) and settings_ok)
