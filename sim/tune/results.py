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

A results file is judged as it is read, line by line, in bounded memory:
it may hold at most :data:`MAX_RESULTS_BYTES` (checked on the open file
before anything is read) and each line at most :data:`MAX_ROW_BYTES`; the
first line that is not a result row is refused at once, naming the file,
the line number and the reason.

Only the process that drives the sweep writes the file, each row as one
``write`` of the whole encoded line followed by an ``fsync``, so an
interrupted sweep keeps every finished row.  If a write fails (a full disk:
``ENOSPC``), the file is cut back to its size before that row, so no torn
row is left, and the sweep stops with a :class:`~sim.tune.spec.TuneError`
(exit 2) ``PATH: no space left on device``.  The summary files beside it (``NAME.md``, ``NAME.html``,
``NAME-*.png``) are replaced atomically.
"""

from __future__ import annotations

import errno
import json
import os
import stat
from pathlib import Path

from .spec import KEY_FIELDS, RunSpec, TuneError

__all__ = ["MAX_RESULTS_BYTES", "MAX_ROW_BYTES", "ResultsFile", "check_output", "read_results", "row_key", "summary_path"]

ROW_PREFIX = b'{"scenario": '
"""How every row written by a sweep begins (``json.dumps`` of a row: its first key is the scenario)."""

MAX_RESULTS_BYTES = 256 << 20
"""The largest results file a sweep appends to or summarizes [bytes] (some 250 000 rows)."""

MAX_ROW_BYTES = 1 << 20
"""The longest line of a results file [bytes]; a row written by a sweep is about 1 KB."""

_CHUNK = 1 << 20
_SUMMARY_SUFFIXES = (".md", ".html")


def read_results(path: str | Path) -> list[dict]:
    """The rows of a results file, in file order.

    A torn last line (a sweep killed while writing) and lines that are not
    result rows are left out.  Read line by line; raises :class:`TuneError`
    when the file cannot be read, is larger than :data:`MAX_RESULTS_BYTES`
    or has a line longer than :data:`MAX_ROW_BYTES`.
    """
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        raise TuneError(f"{path}: cannot read the results file: {exc.strerror or exc}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise TuneError(f"{path}: cannot read the results file: not a regular file")
        _check_size(path, st.st_size, "")
        rows = []
        for _, line, complete in _lines(path, fd, ""):
            if complete:
                row = _row(line)
                if row is not None:
                    rows.append(row)
        return rows
    except OSError as exc:
        raise TuneError(f"{path}: cannot read the results file: {exc.strerror or exc}") from None
    finally:
        os.close(fd)


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
            _scan(path, fd)
        finally:
            os.close(fd)
    for suffix in _SUMMARY_SUFFIXES:
        side = summary_path(path, suffix)
        if side.is_dir() and not side.is_symlink():
            raise TuneError(f"--output: {side}: is a directory; the sweep writes its summary there")
        if os.path.lexists(side) and not is_our_summary(side):
            raise TuneError(f"--output: {side}: not written by swarmform tune, so not replaced by its summary; "
                            "move it away or choose another -o")
    return path


SUMMARY_MARK = "<!-- swarmform tune summary: replaced by the next summary of its results file -->"
"""The first line of every ``NAME.md`` (the line after ``<!DOCTYPE html>`` of ``NAME.html``)
that the sweep writes: only a file that starts so is ever replaced."""


def is_our_summary(path: Path) -> bool:
    """Whether ``path`` is a regular file (not a link) whose first lines hold :data:`SUMMARY_MARK`."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError:
        return False
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return False
        head = os.read(fd, 512)
    finally:
        os.close(fd)
    return SUMMARY_MARK.encode() in head


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
            self.rows, end, size = _scan(path, self._fd)
            if end < size:
                os.ftruncate(self._fd, end)
                os.fsync(self._fd)
                print(f"swarmform tune: {path}: cut off a torn last line ({size - end} bytes)", file=log)
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
        """Add one row as one line: one ``os.write`` of the whole line, then fsync.

        A short write is completed; a failed one (a full disk, an I/O error)
        cuts the file back to its size before the row, so it never ends in
        a torn row.  ``ENOSPC`` becomes :class:`TuneError`
        ``PATH: no space left on device`` (exit 2).
        """
        data = (json.dumps(row, allow_nan=False, ensure_ascii=False) + "\n").encode("utf-8")
        if not data.startswith(ROW_PREFIX):
            raise ValueError(f"a row must begin with its scenario, got {data[:40]!r}")
        if len(data) > MAX_ROW_BYTES:
            raise ValueError(f"a row may have at most {MAX_ROW_BYTES} bytes, got {len(data)}")
        before = os.fstat(self._fd).st_size
        try:
            done = os.write(self._fd, data)
            while done < len(data):
                done += os.write(self._fd, data[done:])
            os.fsync(self._fd)
        except OSError as exc:
            try:
                os.ftruncate(self._fd, before)
                os.fsync(self._fd)
            except OSError:
                pass
            if exc.errno in (errno.ENOSPC, errno.EDQUOT):
                raise TuneError(f"{self.path}: no space left on device") from None
            raise
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


def _check_size(path: Path, size: int, prefix: str = "--output: ") -> None:
    if size > MAX_RESULTS_BYTES:
        raise TuneError(f"{prefix}{path}: is {size / (1 << 20):.4g} MiB, larger than the "
                        f"{MAX_RESULTS_BYTES >> 20} MiB a results file may have")


def _lines(path: Path, fd: int, prefix: str = "--output: "):
    """``(number, line, complete)`` of the file, from its start, never holding more than a line and a chunk.

    The last item has ``complete`` false when the file does not end in a
    newline (``line`` is then what follows the last newline).  Refuses a
    line longer than :data:`MAX_ROW_BYTES` and a file that grows past
    :data:`MAX_RESULTS_BYTES` while it is read.
    """
    os.lseek(fd, 0, os.SEEK_SET)
    pending = b""
    n = total = 0
    while chunk := os.read(fd, _CHUNK):
        total += len(chunk)
        if total > MAX_RESULTS_BYTES:
            _check_size(path, total, prefix)
        start = 0
        while (nl := chunk.find(b"\n", start)) >= 0:
            n += 1
            line = pending + chunk[start:nl] if pending else chunk[start:nl]
            pending = b""
            if len(line) > MAX_ROW_BYTES:
                _too_long(path, n, prefix)
            yield n, line, True
            start = nl + 1
        pending += chunk[start:]
        if len(pending) > MAX_ROW_BYTES:
            _too_long(path, n + 1, prefix)
    if pending:
        yield n + 1, pending, False


def _too_long(path: Path, n: int, prefix: str):
    raise TuneError(f"{prefix}{path}: is not a results file (line {n} is longer than the "
                    f"{MAX_ROW_BYTES >> 20} MiB a result row may have); give a new file or one a sweep wrote")


def _scan(path: Path, fd: int) -> tuple[list[dict], int, int]:
    """The rows of an open results file, where its complete lines end and its size.

    Judged line by line: a file that is not a results file is refused at
    its first wrong line, with only that line read past.
    """
    _check_size(path, os.fstat(fd).st_size)
    rows = []
    end = size = 0
    for n, line, complete in _lines(path, fd):
        size += len(line) + complete
        if not complete:
            if not line.startswith(ROW_PREFIX[: len(line)]):
                raise TuneError(f"--output: {path}: is not a results file (its last line is not a result row); "
                                "give a new file or one a sweep wrote")
            break
        row = _row(line)
        if row is None:
            raise TuneError(f"--output: {path}: is not a results file (line {n} is not a result row); "
                            "give a new file or one a sweep wrote")
        rows.append(row)
        end = size
    return rows, end, size


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
