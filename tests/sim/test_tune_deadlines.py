"""Every network wait of ``swarmform tune --scheduler`` has a deadline.

A peer on loopback that accepts the TCP connection and then stays silent,
sends garbage, or closes the connection (at once, or after reading Dask's
handshake), and a Dask comm that completes the handshake but never sends the
first reply (silent, or closing), end the real command line within a bound:
one line on stderr, exit 4, no traceback, no stray Dask log lines, and no
thread left that keeps the process from exiting.  The listeners are threads of this test process, or
a small process of it (the Dask comm), and stop by themselves.  A port where
nothing listens stays exit 2 (see test_tune_zz_cluster.py).
"""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parents[2]
FIG1 = ROOT / "scenarios" / "paper" / "fig1-line-to-phi.yaml"
BOUND_S = 20.0  # the connect deadline is 11 s; the rest is Python and Dask starting up
LISTEN_S = 45.0  # a listener stops by itself after this long


class Listener:
    """A TCP listener on 127.0.0.1 that treats each connection as ``mode`` says, for at most ``LISTEN_S``."""

    def __init__(self, mode: str):
        self.mode = mode
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.accepted = 0
        self.read: list[bytes] = []
        self._stop = threading.Event()
        self._held: list[socket.socket] = []
        self._thread = threading.Thread(target=self._serve, daemon=True)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join(5)
        for c in self._held:
            c.close()
        self.sock.close()
        return False

    def _serve(self) -> None:
        end = time.monotonic() + LISTEN_S
        while not self._stop.is_set() and time.monotonic() < end:
            try:
                conn, _ = self.sock.accept()
            except (socket.timeout, OSError):
                continue
            self.accepted += 1
            if self.mode == "silent":
                self._held.append(conn)  # open, never a byte
            elif self.mode == "garbage":
                try:
                    conn.sendall(b"\xde\xad\xbe\xef not dask \x00\x01\x02" * 16)
                except OSError:
                    pass
                self._held.append(conn)
            elif self.mode == "close":
                conn.close()
            elif self.mode == "read-then-close":
                conn.settimeout(3)
                try:
                    self.read.append(conn.recv(65536))
                except OSError:
                    pass
                conn.close()


def _tune(port: int, tmp_path: Path) -> tuple[int, str, float]:
    argv = [sys.executable, "-m", "sim.cli", "tune", str(FIG1), "--scheduler", f"tcp://127.0.0.1:{port}",
            "--seeds", "1", "--no-progress", "-o", str(tmp_path / "r.jsonl")]
    start = time.monotonic()
    proc = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=60)
    return proc.returncode, proc.stderr, time.monotonic() - start


def _assert_one_line_exit_4(code: int, err: str, took: float, port: int) -> None:
    assert code == 4, err
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f"swarmform tune: error: --scheduler: tcp://127.0.0.1:{port} accepted the connection")
    assert "Traceback" not in err
    assert took < BOUND_S, f"took {took:.1f} s"


def test_the_silent_listener_hangs_a_bare_client():
    """Negative control: without a deadline, a read from the silent listener never returns."""
    with Listener("silent") as peer:
        with socket.create_connection(("127.0.0.1", peer.port), timeout=5) as c:
            c.settimeout(2.0)
            with pytest.raises(socket.timeout):
                c.recv(1)
        assert peer.accepted == 1


# "silent" waits out the real deadlines (about 12 s): in the slow run
@pytest.mark.parametrize("mode", [pytest.param("silent", marks=pytest.mark.slow), "garbage", "close", "read-then-close"])
def test_a_peer_that_is_not_a_scheduler_is_one_line_and_exit_4(mode, tmp_path):
    with Listener(mode) as peer:
        code, err, took = _tune(peer.port, tmp_path)
        accepted = peer.accepted
        read = list(peer.read)
    print(f"{mode}: exit {code} after {took:.1f} s: {err.strip()}")
    _assert_one_line_exit_4(code, err, took, peer.port)
    assert accepted >= 1  # the command did reach the listener
    if mode == "read-then-close":
        assert any(read), "the listener read no handshake"
    assert not (tmp_path / "r.jsonl").exists() or not (tmp_path / "r.jsonl").read_text()


_FAKE_SCHEDULER = """
import asyncio, sys
from distributed.comm import listen

async def handler(comm):
    try:
        await comm.read()  # the client's first message, after a real Dask handshake
        if sys.argv[1] == "silent":
            await asyncio.sleep(%(life)s)  # never the reply
        await comm.close()
    except Exception:
        pass

async def main():
    server = listen("tcp://127.0.0.1:0", handler)
    await server.start()
    print(server.listen_address.rsplit(":", 1)[1], flush=True)
    await asyncio.sleep(%(life)s)  # then it stops by itself
    server.stop()

asyncio.run(main())
""" % {"life": LISTEN_S}


@pytest.mark.parametrize("mode", [pytest.param("silent", marks=pytest.mark.slow), "close"])
def test_a_peer_that_shakes_hands_and_never_replies_is_one_line_and_exit_4(mode, tmp_path):
    """A Dask comm that completes the handshake, reads the client's first message, then is silent or closes."""
    script = tmp_path / "fake_scheduler.py"
    script.write_text(_FAKE_SCHEDULER)
    fake = subprocess.Popen([sys.executable, str(script), mode], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True)
    try:
        port = int(fake.stdout.readline())
        code, err, took = _tune(port, tmp_path)
    finally:
        fake.kill()
        fake.wait(10)
    print(f"handshake-then-{mode}: exit {code} after {took:.1f} s: {err.strip()}")
    _assert_one_line_exit_4(code, err, took, port)
