"""Reading input files that may be hostile, and echoing what they hold.

:func:`read_text` reads a whole text file only when it is a regular file of
at most ``max_bytes``: the path is ``stat``-ed before it is opened (a FIFO,
a device such as ``/dev/zero``, a socket or a directory is refused without
being opened, so nothing blocks), it is opened non-blocking, checked again
on the open descriptor, and never more than ``max_bytes + 1`` bytes are
read (files whose size is not known in advance, as in ``/proc``, included).

:func:`echo` renders a received value for an error message in at most about
80 characters: long strings and paths are cut with a note of their length,
containers are summarised by their size, and integers too long to print are
given by their number of digits.  :class:`HugeInt` stands for an integer
literal too long to convert (Python refuses ``int()`` of more than 4300
digits); the YAML and JSON readers return it instead of raising, so that
the field holding it can be named.

:func:`load_json` parses a JSON document read by :func:`read_text` in
bounded memory: it counts the lists and objects (``[`` and ``{``) before
anything is built and refuses more than ``max_containers`` of them (a file
padded with millions of empty ``[]`` would otherwise cost some 50 times
its size), and refuses an object that repeats a key, naming the key.
"""

from __future__ import annotations

import errno
import math
import os
import stat
from pathlib import Path

__all__ = ["ECHO_LIMIT", "MAX_JSON_CONTAINERS", "HugeInt", "JsonRefused", "UnreadableFile", "echo", "echo_key",
           "echo_path", "load_json", "read_text"]

ECHO_LIMIT = 80
"""The longest rendering of a received value in an error message [characters]."""

MAX_JSON_CONTAINERS = 2_000_000
"""The most lists and objects :func:`load_json` builds by default.

A plan of m robots and K steps has about (K + 1) (m + 1) of them: two
million admit 1000 robots over 1999 steps (or 100 000 steps of 19 robots),
and cost at most some 250 MB once built.
"""


class UnreadableFile(ValueError):
    """A file that is not read; ``str()`` is one short line saying why."""


class JsonRefused(ValueError):
    """A JSON document that is not loaded: ``where`` is ``line L``, ``file`` or the repeated key."""

    def __init__(self, where: str, reason: str):
        self.where, self.reason = where, reason
        super().__init__(f"{where}: {reason}")


def load_json(text: str, *, max_containers: int = MAX_JSON_CONTAINERS, parse_int=None):
    """The JSON document in ``text``, or :class:`JsonRefused` naming where and why.

    Before parsing, refuses a document with more than ``max_containers``
    lists and objects (``[`` and ``{`` are counted wherever they are, so
    ones inside strings count too: the bound is only ever stricter).  While
    parsing, refuses an object that repeats a key (``where`` is the key as
    a field name).  ``parse_int`` is passed to :func:`json.loads`.
    """
    import json

    containers = text.count("[") + text.count("{")
    if containers > max_containers:
        raise JsonRefused("file", f"holds {containers} lists and objects, more than the {max_containers} "
                                  "a file may have")

    def pairs(items):
        d = {}
        for key, value in items:
            if key in d:
                raise JsonRefused(echo_key(key), "is given twice (a JSON object may not repeat a key)")
            d[key] = value
        return d

    try:
        return json.loads(text, parse_int=parse_int, object_pairs_hook=pairs)
    except json.JSONDecodeError as exc:
        raise JsonRefused(f"line {exc.lineno}", f"invalid JSON: {exc.msg}") from None
    except RecursionError:
        raise JsonRefused("file", "nests lists or objects too deeply") from None


class HugeInt:
    """An integer literal with too many digits to be any field's value."""

    __slots__ = ("digits", "negative")

    def __init__(self, literal: str):
        text = literal.strip().replace("_", "")
        self.negative = text.startswith("-")
        self.digits = len(text.lstrip("+-"))

    def __repr__(self) -> str:
        return f"{'-' if self.negative else ''}<a {self.digits}-digit integer>"


def echo(value, limit: int = ECHO_LIMIT) -> str:
    """``value`` described for an error message in at most about ``limit`` characters."""
    if value is None:
        return "nothing (null)"
    if isinstance(value, bool):
        return f"boolean {value}"
    if isinstance(value, HugeInt):
        return f"an integer of {value.digits} digits"
    if isinstance(value, int):
        if value.bit_length() > 64:
            return f"an integer of about {math.ceil(value.bit_length() * math.log10(2))} digits"
        return f"number {value}"
    if isinstance(value, float):
        return f"number {value!r}"
    if isinstance(value, str):
        return "string " + _cut_repr(value, limit - 7)
    if isinstance(value, (list, tuple)):
        return f"a list of {len(value)}"
    if isinstance(value, dict):
        return f"a mapping of {len(value)} keys" if len(value) != 1 else "a mapping of 1 key"
    if isinstance(value, (bytes, bytearray)):
        return f"{len(value)} bytes of binary data"
    name = type(value).__name__
    return f"a {name[:40]}"


def echo_key(key, limit: int = 24) -> str:
    """A mapping key as it goes into a field name (``robots.radius``), short."""
    if isinstance(key, str):
        plain = key and key.isprintable() and key.strip() == key and ":" not in key
        text = key if plain else repr(key)
        return text if len(text) <= limit else text[: limit - 3] + "..."
    return echo(key, limit)


def _cut_repr(text: str, limit: int) -> str:
    if len(text) <= limit:
        r = repr(text)
        if len(r) <= limit + 2:
            return r
    head = repr(text[: max(8, limit // 4)])[:-1]
    return f"{head}...' ({len(text)} characters)"


def echo_path(path, limit: int = 100) -> str:
    """A path as it is named in a one-line message: the end kept when it is long."""
    text = str(path)
    if not text.isprintable():
        text = repr(text)[1:-1]
    if len(text) <= limit:
        return text
    return "..." + text[-(limit - 3):]


def read_text(path: str | Path, max_bytes: int) -> str:
    """The UTF-8 text of a regular file of at most ``max_bytes`` bytes.

    Raises :class:`UnreadableFile` with the reason (no such file, a
    directory, not a regular file, too large, not readable, not UTF-8).
    Never opens what is not a regular file and never blocks on one.
    """
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise UnreadableFile("no such file") from None
    except NotADirectoryError:
        raise UnreadableFile("no such file (a part of the path is not a folder)") from None
    except ValueError:
        raise UnreadableFile("is not a valid path (it holds a NUL character)") from None
    except OSError as exc:
        raise UnreadableFile(f"cannot be read ({_os_reason(exc)})") from None
    _check_mode(st, max_bytes)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise UnreadableFile(f"cannot be read ({_os_reason(exc)})") from None
    try:
        _check_mode(os.fstat(fd), max_bytes)  # the path may have changed since stat
        chunks, size = [], 0
        while size <= max_bytes:
            chunk = os.read(fd, min(1 << 20, max_bytes + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as exc:
        raise UnreadableFile(f"cannot be read ({_os_reason(exc)})") from None
    finally:
        os.close(fd)
    if size > max_bytes:
        raise UnreadableFile(f"is larger than the {_size(max_bytes)} an input file may have")
    data = b"".join(chunks)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise UnreadableFile(f"is not UTF-8 text (byte {exc.start} is {data[exc.start]:#04x})") from None


def _check_mode(st: os.stat_result, max_bytes: int) -> None:
    mode = st.st_mode
    if stat.S_ISDIR(mode):
        raise UnreadableFile("is a folder, not a file")
    if not stat.S_ISREG(mode):
        kind = (
            "a FIFO" if stat.S_ISFIFO(mode)
            else "a character device" if stat.S_ISCHR(mode)
            else "a block device" if stat.S_ISBLK(mode)
            else "a socket" if stat.S_ISSOCK(mode)
            else "not a regular file"
        )
        raise UnreadableFile(f"is {kind}, not a regular file")
    if st.st_size > max_bytes:
        raise UnreadableFile(
            f"is {_size(st.st_size)}, larger than the {_size(max_bytes)} an input file may have"
        )


def _size(n: int) -> str:
    if n >= 1 << 20:
        return f"{n / (1 << 20):.4g} MiB"
    if n >= 1 << 10:
        return f"{n / (1 << 10):.4g} KiB"
    return f"{n} bytes"


def _os_reason(exc: OSError) -> str:
    if exc.errno is not None and exc.errno in errno.errorcode:
        return os.strerror(exc.errno)
    return type(exc).__name__
