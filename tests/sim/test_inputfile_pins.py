"""Exact messages and boundaries of the hostile-input reader (planner/inputfile.py).

Each test pins one behaviour a user sees in an error line: the wording, the cut, the
size at which a file is refused.  They are the tests that mutation testing of
``planner/inputfile.py`` relies on (see ``tests/mutation/``).
"""

import errno
import os
import socket
import stat

import pytest

from planner.inputfile import (
    ECHO_LIMIT,
    HugeInt,
    UnreadableFile,
    _check_mode,
    _os_reason,
    _size,
    echo,
    echo_key,
    echo_path,
    read_text,
)


def test_huge_int_counts_digits_and_sign():
    h = HugeInt(" -1_000_000 ")
    assert (h.negative, h.digits) == (True, 7)
    assert repr(h) == "-<a 7-digit integer>"
    h = HugeInt("+12345")
    assert (h.negative, h.digits) == (False, 5)
    assert repr(h) == "<a 5-digit integer>"


@pytest.mark.parametrize(
    "value, text",
    [
        (None, "nothing (null)"),
        (True, "boolean True"),
        (False, "boolean False"),
        (HugeInt("9" * 5000), "an integer of 5000 digits"),
        (7, "number 7"),
        (2**64 - 1, "number 18446744073709551615"),
        (2**64, "an integer of about 20 digits"),
        (10**30, "an integer of about 31 digits"),
        (1.5, "number 1.5"),
        (float("inf"), "number inf"),
        ("abc", "string 'abc'"),
        ([1, 2, 3], "a list of 3"),
        ((1,), "a list of 1"),
        ({}, "a mapping of 0 keys"),
        ({"a": 1}, "a mapping of 1 key"),
        ({"a": 1, "b": 2}, "a mapping of 2 keys"),
        (b"\x00\x01", "2 bytes of binary data"),
        (bytearray(3), "3 bytes of binary data"),
        (object(), "a object"),
        (type("N" * 60, (), {})(), "a " + "N" * 40),
    ],
)
def test_echo_names_the_kind_and_value(value, text):
    assert echo(value) == text


def test_echo_cuts_long_strings_at_the_limit():
    assert ECHO_LIMIT == 80
    exact = "x" * 73  # the longest string shown whole: 'string ' and its repr, 82 characters
    assert echo(exact) == f"string '{exact}'"
    assert echo("x" * 74) == "string 'xxxxxxxxxxxxxxxxxx...' (74 characters)"
    assert len(echo("y" * 10**6)) <= ECHO_LIMIT
    assert echo("y" * 10**6) == "string 'yyyyyyyyyyyyyyyyyy...' (1000000 characters)"
    # a short string whose repr grows (escapes) past the limit is cut too
    assert echo("\x00" * 30, limit=40) == "string '\\x00\\x00\\x00\\x00\\x00\\x00\\x00\\x00...' (30 characters)"
    assert echo("ab", limit=16) == "string 'ab'"
    assert echo("abcdefghij", limit=16) == "string 'abcdefgh...' (10 characters)"


def test_echo_key_is_plain_when_it_can_be():
    assert echo_key("radius") == "radius"
    assert echo_key("a" * 24) == "a" * 24
    assert echo_key("a" * 25) == "a" * 21 + "..."
    assert echo_key("a b") == "a b"
    assert echo_key(" a") == "' a'"
    assert echo_key("a:b") == "'a:b'"
    assert echo_key("a\nb") == "'a\\nb'"
    assert echo_key("") == "''"
    assert echo_key(3) == "number 3"
    assert echo_key(None) == "nothing (null)"
    assert echo_key("b" * 10, limit=8) == "bbbbb..."


def test_echo_path_keeps_the_end():
    assert echo_path("a/b.yaml") == "a/b.yaml"
    p = "d/" * 60 + "end.yaml"
    assert echo_path(p) == "..." + p[-97:]
    assert len(echo_path(p)) == 100
    assert echo_path("x" * 100) == "x" * 100
    assert echo_path("a\nb") == "a\\nb"
    assert echo_path("abcdefghij", limit=8) == "...fghij"


def test_read_text_reads_a_file_of_exactly_the_cap(tmp_path):
    f = tmp_path / "s.yaml"
    f.write_bytes(b"a" * 100)
    assert read_text(f, 100) == "a" * 100
    assert read_text(str(f), 1000) == "a" * 100
    with pytest.raises(UnreadableFile) as e:
        read_text(f, 99)
    assert str(e.value) == "is 100 bytes, larger than the 99 bytes an input file may have"


def test_read_text_reads_more_than_one_chunk(tmp_path):
    f = tmp_path / "big.yaml"
    text = ("0123456789abcdef" * (1 << 17))  # 2 MiB: three reads of at most 1 MiB
    f.write_text(text)
    assert read_text(f, 3 << 20) == text


def test_read_text_stops_at_the_cap_when_the_size_is_unknown():
    # /proc files report size 0 and hold more
    path = "/proc/self/maps"
    if not os.path.exists(path):
        pytest.skip("no /proc")
    with pytest.raises(UnreadableFile) as e:
        read_text(path, 10)
    assert str(e.value) == "is larger than the 10 bytes an input file may have"
    assert read_text("/proc/self/maps", 1 << 24).count("\n") > 1


def test_read_text_names_why(tmp_path):
    cases = {
        tmp_path / "none.yaml": "no such file",
        tmp_path / "x" / "y.yaml": "no such file",
        tmp_path: "is a folder, not a file",
        "/dev/zero": "is a character device, not a regular file",
        "a\0b": "is not a valid path (it holds a NUL character)",
    }
    (tmp_path / "file").write_text("x")
    cases[tmp_path / "file" / "y.yaml"] = "no such file (a part of the path is not a folder)"
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    cases[fifo] = "is a FIFO, not a regular file"
    sock_path = tmp_path / "s.sock"
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(sock_path))
    cases[sock_path] = "is a socket, not a regular file"
    bad = tmp_path / "bad.yaml"
    bad.write_bytes(b"ok\n\xff")
    cases[bad] = "is not UTF-8 text (byte 3 is 0xff)"
    loop = tmp_path / "loop"
    os.symlink(loop, loop)
    cases[loop] = "cannot be read (Too many levels of symbolic links)"
    try:
        for path, reason in cases.items():
            with pytest.raises(UnreadableFile) as e:
                read_text(path, 1000)
            assert str(e.value) == reason, path
    finally:
        sock.close()


def test_read_text_reports_a_file_it_may_not_open_or_read(tmp_path, monkeypatch):
    f = tmp_path / "secret.yaml"
    f.write_text("x")
    real_open, real_read = os.open, os.read

    def refuse(*args, **kwargs):
        raise PermissionError(errno.EACCES, "denied")

    monkeypatch.setattr(os, "open", refuse)
    with pytest.raises(UnreadableFile, match=r"^cannot be read \(Permission denied\)$"):
        read_text(f, 10)
    monkeypatch.setattr(os, "open", real_open)
    monkeypatch.setattr(os, "read", lambda *a: (_ for _ in ()).throw(OSError(errno.EIO, "io")))
    with pytest.raises(UnreadableFile, match=r"^cannot be read \(Input/output error\)$"):
        read_text(f, 10)
    monkeypatch.setattr(os, "read", real_read)
    assert read_text(f, 10) == "x"


def test_read_text_opens_without_blocking(tmp_path, monkeypatch):
    f = tmp_path / "s.yaml"
    f.write_text("x")
    seen = []
    real_open = os.open
    monkeypatch.setattr(os, "open", lambda path, flags, *a: seen.append(flags) or real_open(path, flags, *a))
    read_text(f, 10)
    assert seen == [os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY]


def test_read_text_checks_the_opened_file_again(tmp_path, monkeypatch):
    f = tmp_path / "s.yaml"
    f.write_text("x" * 50)
    small = os.stat(f)
    real_stat = os.stat
    # the path grows between stat and open: the check on the descriptor refuses it
    monkeypatch.setattr(os, "stat", lambda p, *a, **k: small if str(p) == str(f) else real_stat(p, *a, **k))
    f.write_text("x" * 500)
    with pytest.raises(UnreadableFile, match=r"^is 500 bytes, larger than the 100 bytes"):
        read_text(f, 100)


def test_read_text_stat_errors_are_named(monkeypatch):
    monkeypatch.setattr(os, "stat", lambda *a, **k: (_ for _ in ()).throw(OSError(errno.EACCES, "x")))
    with pytest.raises(UnreadableFile, match=r"^cannot be read \(Permission denied\)$"):
        read_text("whatever.yaml", 10)


def test_check_mode_names_block_devices_and_others():
    def st(mode, size=0):
        return os.stat_result((mode, 0, 0, 0, 0, 0, size, 0, 0, 0))

    with pytest.raises(UnreadableFile, match=r"^is a block device, not a regular file$"):
        _check_mode(st(stat.S_IFBLK), 10)
    with pytest.raises(UnreadableFile, match=r"^is not a regular file, not a regular file$"):
        _check_mode(st(0), 10)
    _check_mode(st(stat.S_IFREG, 10), 10)
    with pytest.raises(UnreadableFile, match=r"^is 11 bytes, larger than the 10 bytes"):
        _check_mode(st(stat.S_IFREG, 11), 10)


@pytest.mark.parametrize(
    "n, text",
    [
        (0, "0 bytes"),
        (1023, "1023 bytes"),
        (1024, "1 KiB"),
        (1536, "1.5 KiB"),
        ((1 << 20) - 1, "1024 KiB"),
        (1 << 20, "1 MiB"),
        (5 << 20, "5 MiB"),
        (12345678, "11.77 MiB"),
    ],
)
def test_size_is_short(n, text):
    assert _size(n) == text


def test_os_reason_is_the_system_message_or_the_class():
    assert _os_reason(OSError(errno.EACCES, "x")) == "Permission denied"
    assert _os_reason(OSError("no errno")) == "OSError"
    assert _os_reason(PermissionError(99999, "x")) == "PermissionError"


def test_a_short_string_whose_repr_grows_past_the_limit_is_cut():
    # 73 characters fit whole; one of them a newline makes the repr 76 long
    assert echo("a" * 72 + "\n") == "string 'aaaaaaaaaaaaaaaaaa...' (73 characters)"
    assert echo("a" * 71 + "\n") == "string '" + "a" * 71 + "\\n'"


def test_a_file_that_grows_while_it_is_read_is_refused(tmp_path, monkeypatch):
    # the size checks see 8 bytes; the reads find 12, a few bytes at a time
    f = tmp_path / "grows.yaml"
    f.write_text("x" * 8)
    small = os.stat(f)
    f.write_text("x" * 12)
    real_read = os.read
    monkeypatch.setattr(os, "stat", lambda *a, **k: small)
    monkeypatch.setattr(os, "fstat", lambda *a, **k: small)
    monkeypatch.setattr(os, "read", lambda fd, n: real_read(fd, min(n, 3)))
    with pytest.raises(UnreadableFile, match=r"^is larger than the 9 bytes an input file may have$"):
        read_text(f, 9)
    assert read_text(f, 12) == "x" * 12
